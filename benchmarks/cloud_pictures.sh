#!/bin/bash
# Cloud pictures (issue 46, item 5): the WDAS cloud at 1/16 (../shared/data; credit Walt Disney
# Animation Studios, CC BY-SA 3.0) solved under a sun 45 degrees up, isotropic and at g 0.877
# (moments written to order 8), then rendered: how far the picture from fewer moments is from
# order 8's, how much the march step matters, and docs/wdas-cloud.png. ~12 min on 2 cores.
# Usage: benchmarks/cloud_pictures.sh [BUILD_DIR] [WORK_DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$here/build}
work=${2:-/tmp/vdbrad-cloud-pictures}
data=$here/../shared/data/wdas_cloud_sixteenth.vdb
mkdir -p "$work"
cd "$work"
V=$build/vdbrad
/usr/bin/time -f "g 0.877 solve: %e s wall, %M KB peak" $V solve-cloud "$data" w877.vdb \
    --g 0.877 --sun 45,0 --tolerance 1e-4 --quiet
/usr/bin/time -f "isotropic solve: %e s wall, %M KB peak" $V solve-cloud "$data" w0.vdb \
    --sun 45,0 --tolerance 1e-4 --quiet
PYTHONPATH=$build/python /usr/bin/python3 "$here/benchmarks/cloud_pictures.py" \
    "$here/docs/wdas-cloud.png"
