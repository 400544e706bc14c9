"""Extract the ASTM G173-03 extraterrestrial spectrum into ``solar_spectrum_astm_g173.csv``.

Reads the copy of the ASTM G173-03 tables that ships in the pvlib wheel
(``pvlib/data/ASTMG173.csv``: columns wavelength, extraterrestrial, global, direct; W m^-2 nm^-1)
and writes the wavelength and extraterrestrial columns between 330 and 830 nm, at the native
resolution (0.5 nm below 400 nm, 1 nm above), keeping each number exactly as it is written in the
source (no reformatting, so the extraction is lossless and byte-for-byte reproducible).

Run from anywhere::

    python skymodel/data/generated/make_solar_spectrum.py                 # pvlib's copy -> next to this script
    python skymodel/data/generated/make_solar_spectrum.py --source ASTMG173.csv --output /tmp/out.csv

pvlib is needed only to locate its data file (``--source`` avoids even that); skymodel reads the
CSV this script writes and never imports pvlib at run time.
"""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

#: Wavelength range carried, nm. Wider than 380-780 nm so that a band of up to 100 nm centred on
#: any wavelength of the visible grid stays inside the table (skymodel.sun.MAX_BANDWIDTH_NM).
RANGE_NM = (330.0, 830.0)
OUTPUT_NAME = "solar_spectrum_astm_g173.csv"

HEADER = """\
# Extraterrestrial (top of atmosphere, 1 AU) solar spectral irradiance, W m^-2 nm^-1.
#
# Source: ASTM G173-03, "Standard Tables for Reference Solar Spectral Irradiances: Direct Normal and
#   Hemispherical on 37 deg Tilted Surface", the extraterrestrial (ETR) column. The tables were
#   generated with SMARTS v2.9.2 (C. A. Gueymard; so says the first line of the source file); its
#   ETR is Gueymard's extraterrestrial spectrum (C. A. Gueymard 2004, Solar Energy 76, 423-453),
#   which descriptions of the standard also trace to the Wehrli (1985) ETR (WRC Publ. 615, Davos).
#   The whole tabulated ETR (280-4000 nm) integrates to 1347.9 W m^-2 (trapezoid, computed here).
# Extracted by skymodel/data/generated/make_solar_spectrum.py from the copy shipped in the pvlib wheel,
#   pvlib/data/ASTMG173.csv (checked with pvlib 0.16.1, which copies it from the NREL/NLR "Reference
#   Air Mass 1.5 Spectra" workbook): the rows with {lo:g} <= wavelength <= {hi:g} nm, columns
#   wavelength and extraterrestrial, numbers copied verbatim as text. Native resolution: 0.5 nm
#   below 400 nm, 1 nm from 400 nm on.
# Check values (native table): 500 nm 1.916, 600 nm 1.770, 700 nm 1.422 W m^-2 nm^-1.
"""


def default_source() -> Path:
    spec = importlib.util.find_spec("pvlib")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("pvlib is not installed: pass --source path/to/ASTMG173.csv")
    return Path(list(spec.submodule_search_locations)[0]) / "data" / "ASTMG173.csv"


def extract(source: Path, lo: float = RANGE_NM[0], hi: float = RANGE_NM[1]) -> list[tuple[str, str]]:
    """Return (wavelength, extraterrestrial) as the source's own strings for lo <= wavelength <= hi."""
    rows = []
    with open(source, encoding="utf-8") as f:
        lines = f.read().splitlines()
    header = [h.strip().lower() for h in lines[1].split(",")]
    i_wl, i_etr = header.index("wavelength"), header.index("extraterrestrial")
    for line in lines[2:]:
        if not line.strip():
            continue
        cells = [c.strip() for c in line.split(",")]
        wl = float(cells[i_wl])
        if lo <= wl <= hi:
            float(cells[i_etr])  # must parse
            rows.append((cells[i_wl], cells[i_etr]))
    return rows


def write(rows: list[tuple[str, str]], output: Path) -> None:
    text = HEADER.format(lo=RANGE_NM[0], hi=RANGE_NM[1])
    text += "wavelength_nm,irradiance_W_m2_nm\n"
    text += "".join(f"{w},{e}\n" for w, e in rows)
    output.write_text(text, encoding="utf-8", newline="\n")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", type=Path, default=None, help="ASTMG173.csv (default: pvlib's copy)")
    parser.add_argument("--output", type=Path, default=Path(__file__).resolve().parent / OUTPUT_NAME)
    args = parser.parse_args(argv)
    source = args.source or default_source()
    rows = extract(source)
    write(rows, args.output)
    print(f"wrote {len(rows)} rows {rows[0][0]}-{rows[-1][0]} nm to {args.output}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
