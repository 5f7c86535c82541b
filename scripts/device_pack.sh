#!/usr/bin/env bash
# Packs what the device check needs beyond a bare Python with numpy, scipy, matplotlib
# (rich too: Taichi needs it), for a GPU machine without a network (scripts/device_check.sh): Taichi and
# the packages `taimill run` imports (zarr, numcodecs, google-crc32c, donfig, PyYAML,
# fsspec, msgpack, dill, colorama, packaging, typing_extensions), in the versions this
# environment runs, as wheels for that machine's Python, unpacked, without what a run
# never loads (taichi/_lib/c_api, taichi/examples, *.data), then zipped: Taichi's
# library alone is 104 MB unpacked, and the tree that travels holds 64 MiB in all. The
# check unpacks it there (Python's zipfile: nothing is installed or downloaded).
#
#   scripts/device_pack.sh                 → .device/py312.zip (ignored by git)
#   DEVICE_PYTHONS="3.12 3.11" scripts/device_pack.sh    one zip for each version
#   PYTHON=.venv/bin/python scripts/device_pack.sh       the environment whose versions are packed
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-$( [ -x .venv/bin/python ] && echo .venv/bin/python || echo python3 )}
LIMIT_MB=60
PACKAGES="taichi colorama dill rich zarr numcodecs google-crc32c donfig PyYAML fsspec msgpack packaging typing_extensions"
mkdir -p .device
for version in ${DEVICE_PYTHONS:-3.12}; do
    tag="py${version/./}"
    work=$(mktemp -d)
    pins=$($PY -c 'import sys, importlib.metadata as m; print(" ".join(f"{p}=={m.version(p)}" for p in sys.argv[1:]))' $PACKAGES)
    echo "device_pack: Python $version: $pins"
    $PY -m pip download --quiet --no-deps --only-binary=:all: --python-version "$version" --implementation cp \
        --platform manylinux2014_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux_2_27_x86_64 \
        --platform manylinux_2_28_x86_64 -d "$work/wheels" $pins
    $PY - "$work/wheels" "$work/site" ".device/$tag.zip" <<'PYEOF'
import shutil, sys, zipfile
from pathlib import Path

wheels, site, out = map(Path, sys.argv[1:])
for wheel in sorted(wheels.glob("*.whl")):
    with zipfile.ZipFile(wheel) as z:
        z.extractall(site)
for drop in [site / "taichi" / "_lib" / "c_api", site / "taichi" / "examples", *site.glob("*.data"),
             *site.rglob("__pycache__")]:
    shutil.rmtree(drop, ignore_errors=True)
out.unlink(missing_ok=True)
with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as z:
    for f in sorted(p for p in site.rglob("*") if p.is_file()):
        z.write(f, f.relative_to(site))
unpacked = sum(p.stat().st_size for p in site.rglob("*") if p.is_file())
print(f"device_pack: {out}: {out.stat().st_size / 1e6:.1f} MB ({unpacked / 1e6:.0f} MB unpacked)")
PYEOF
    rm -rf "$work"
done
total=$(du -sm .device | cut -f1)
echo "device_pack: .device holds ${total} MB (the tree that travels: 64 MiB in all)"
[ "$total" -le "$LIMIT_MB" ] || { echo "device_pack: over ${LIMIT_MB} MB: pack fewer Python versions" >&2; exit 1; }
echo "device_pack: now run on the device: scripts/device_check.sh (carry [\".device\"])"
