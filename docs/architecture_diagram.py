"""Draw docs/architecture.md's diagram from the code's own imports.

    python docs/architecture_diagram.py            # print the Mermaid block
    python docs/architecture_diagram.py --write    # replace it in docs/architecture.md
    python docs/architecture_diagram.py --check    # exit 1 if the doc is out of date
    python docs/architecture_diagram.py --counts   # print it with import counts on the arrows

The import graph comes from grimp (installed with import-linter, the tool that checks the
same contracts in CI). Each wing of ``skymodel`` (and the add-on) is one box; an arrow
``A --> B`` means some module of A imports some module of B (``--counts`` labels it with
how many module-to-module imports there are; the doc leaves the counts out so that it
changes only when a wing starts or stops depending on another). The base modules
(errors, numerics, geometry, wavelengths, colorimetry, sun, scene) are one box.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "architecture.md"
BEGIN, END = "<!-- diagram:begin (python docs/architecture_diagram.py --write) -->", "<!-- diagram:end -->"

#: Wings, top to bottom; anything else directly under skymodel is "base".
WINGS = ("blender_addon", "skymodel.cli", "skymodel.validation", "skymodel.planner", "skymodel.models",
         "skymodel.render", "skymodel.optics", "skymodel.astro", "skymodel.data")


def wing_of(module: str) -> str | None:
    for w in WINGS:
        if module == w or module.startswith(w + "."):
            return w
    if module.startswith("skymodel.") and module.count(".") == 1 and module != "skymodel.__main__":
        return "base"
    return None  # the package itself, __main__, external packages


def wing_edges() -> Counter:
    import grimp

    sys.path.insert(0, str(ROOT))  # blender_addon is imported from the source tree
    graph = grimp.build_graph("skymodel", "blender_addon", cache_dir=None)
    edges = Counter()
    for importer in graph.modules:
        a = wing_of(importer)
        if a is None:
            continue
        for imported in graph.find_modules_directly_imported_by(importer):
            b = wing_of(imported)
            if b is not None and b != a:
                edges[(a, b)] += 1
    return edges


def mermaid(edges: Counter, counts: bool = False) -> str:
    label = {w: w.replace("skymodel.", "skymodel/").replace(".", "/") + ("/" if w != "base" else "")
             for w in (*WINGS, "base")}
    label["base"] = "base: errors, numerics, geometry, wavelengths, colorimetry, sun, scene"
    ident = {w: w.replace(".", "_") for w in label}
    lines = ["```mermaid", "flowchart TD"]
    for w in (*WINGS, "base"):
        lines.append(f'    {ident[w]}["{label[w]}"]')
    order = (*WINGS, "base")
    for (a, b), n in sorted(edges.items(), key=lambda kv: (order.index(kv[0][0]), order.index(kv[0][1]))):
        lines.append(f"    {ident[a]} -->|{n}| {ident[b]}" if counts else f"    {ident[a]} --> {ident[b]}")
    lines.append("```")
    return "\n".join(lines)


def block() -> str:
    return f"{BEGIN}\n{mermaid(wing_edges())}\n{END}"


def replace_block(text: str, new: str) -> str:
    start, stop = text.index(BEGIN), text.index(END) + len(END)
    return text[:start] + new + text[stop:]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--write", action="store_true", help="replace the diagram in docs/architecture.md")
    g.add_argument("--check", action="store_true", help="exit 1 if docs/architecture.md is out of date")
    g.add_argument("--counts", action="store_true", help="print the diagram with import counts on the arrows")
    args = ap.parse_args(argv)
    if args.counts:
        print(mermaid(wing_edges(), counts=True))
        return 0
    new = block()
    if args.write or args.check:
        text = DOC.read_text(encoding="utf-8")
        updated = replace_block(text, new)
        if args.check:
            if updated != text:
                print("docs/architecture.md's diagram is out of date: python docs/architecture_diagram.py --write")
                return 1
            return 0
        DOC.write_text(updated, encoding="utf-8")
    else:
        print(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
