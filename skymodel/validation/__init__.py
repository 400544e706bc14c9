"""Validation: independent references for the renderer, and what accuracy costs in time.

The Monte Carlo path tracer (the marcher's independent reference), the plane-parallel
layers and the bridge to DISORT (``plane_parallel``, ``disort``), and the accuracy
benchmark (error against a converged reference and against the tracer, time and memory
per quality preset and per knob) with its report, and synthetic optical profiles built
without the data tables (``synthetic``) for the tests and validation benchmarks.
May import: ``render``, ``optics`` and the base modules; never ``cli``, ``planner`` or
``models``.
"""
