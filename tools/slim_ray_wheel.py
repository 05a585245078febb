"""Make a smaller Ray wheel for an offline GPU host whose transfers are capped (64 MiB a call).

`rayvr --workers` needs Ray's core only: the driver, raylet and GCS binaries and the Python
package. The Java jar, the dashboard's web front end and the libraries rayvr never imports
(RLlib, Tune, Serve, Data, Train, LLM) are left out, and RECORD is rewritten to match, so pip
installs the result like the original.

    python tools/slim_ray_wheel.py ray-2.60.0-cp312-cp312-manylinux2014_x86_64.whl OUT_DIR
"""
from __future__ import annotations

import base64
import hashlib
import sys
import zipfile
from pathlib import Path

DROP = ("ray/jars/", "ray/dashboard/client/build/", "ray/rllib/", "ray/tune/", "ray/serve/", "ray/data/",
        "ray/train/", "ray/llm/", "ray/air/examples/")


def slim(wheel: Path, out_dir: Path) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    out = out_dir / wheel.name
    with zipfile.ZipFile(wheel) as src, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as dst:
        record_name = next(n for n in src.namelist() if n.endswith(".dist-info/RECORD"))
        lines = []
        for info in src.infolist():
            if info.filename == record_name or info.filename.startswith(DROP):
                continue
            data = src.read(info)
            dst.writestr(info, data, compress_type=zipfile.ZIP_DEFLATED, compresslevel=9)
            digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
            lines.append(f"{info.filename},sha256={digest},{len(data)}")
        lines.append(f"{record_name},,")
        dst.writestr(record_name, "\n".join(lines) + "\n")
    return out


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    path = slim(Path(sys.argv[1]), Path(sys.argv[2]))
    print(f"{path}: {path.stat().st_size / 2**20:.1f} MiB")
