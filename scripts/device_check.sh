#!/usr/bin/env bash
# The device check (scripts/device_check.py): taimill on a lent GPU machine, one table,
# within 8 minutes, installing nothing. Taichi and the packages `taimill run` needs
# beyond numpy, scipy, matplotlib and rich travel with the tree in .device/:
#
#   here:        scripts/device_pack.sh             (builds .device/py312.zip, 47 MB, ignored by git)
#   the device:  the device tool with carry [".device"] and the command
#                scripts/device_check.sh            (add --json $OUT/check.json to keep the numbers)
#   a dry run:   scripts/device_check.sh --backend cpu --threads 1,2 --quick
#
# Options are device_check.py's: --backend cuda|cpu, --threads 1,4,16, --quick,
# --skip-million, --budget SECONDS, --json FILE.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
zip=".device/$($PY -c 'import sys; print("py%d%d" % sys.version_info[:2])').zip"
if [ -f "$zip" ]; then  # unpacked once, outside the tree (.device must stay small enough to travel)
    site="${TMPDIR:-/tmp}/taimill-device-$(cksum < "$zip" | cut -d' ' -f1)"
    if [ ! -d "$site" ]; then
        rm -rf "$site.partial"
        $PY -m zipfile -e "$zip" "$site.partial" && mv "$site.partial" "$site"
    fi
    export PYTHONPATH="$site${PYTHONPATH:+:$PYTHONPATH}"
fi
if ! $PY -c 'import taichi, zarr' >/dev/null 2>&1; then
    echo "device_check: $PY cannot import taichi and zarr; run scripts/device_pack.sh on a machine with a network" \
         "and carry .device (found: $(ls .device 2>/dev/null | tr '\n' ' '))" >&2
    exit 2
fi
exec $PY scripts/device_check.py "$@"
