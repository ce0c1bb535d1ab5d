"""KF-GINS KF_GINS_Navresult.nav -> time_s,lat_deg,lon_deg on the outaged log's clock (UNIX s).

    python kfgins_to_csv.py OUTDIR/KF_GINS_Navresult.nav OUTDIR/time_offset.json kfgins.csv

navresult columns: week(0) sow(1) lat(2) lon(3) h(4) vn ve vd roll pitch yaw. Times had the offset
in time_offset.json subtracted by mcap_to_kfgins.py; it is added back here (float math in Python
on the text values, so no precision is lost beyond KF-GINS's own %.9lf).
"""

import json
import sys
from decimal import Decimal
from pathlib import Path


def main(nav: str, offset_json: str, out: str) -> None:
    offset = Decimal(repr(json.loads(Path(offset_json).read_text())["offset_s"]))
    n = 0
    with open(nav) as f, open(out, "w") as g:
        g.write("time_s,lat_deg,lon_deg\n")
        for line in f:
            c = line.split()
            if len(c) < 4:
                continue
            t = Decimal(c[1]) + offset
            g.write(f"{t:.9f},{float(c[2]):.10f},{float(c[3]):.10f}\n")
            n += 1
    print(f"{n} rows -> {out}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
