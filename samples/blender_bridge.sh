#!/usr/bin/env bash
# Blender bridge, headless: vdbrad's radiosity of a Blender scene baked into a colour attribute
# on its meshes and rendered by Cycles (samples/blender_bridge.py says how). Needs Debian's
# `blender` (3.4; it runs the system's Python, where python3-openvdb provides pyopenvdb).
# Usage: blender_bridge.sh [--blend scene.blend | --obj mesh.obj] [--res N] [--directions N]
#        [--size WxH] [--samples N]   (default: the Cornell box; writes ./blender_bridge/)
# Not part of CI (Blender is not a build dependency).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
export VDBRAD=${VDBRAD:-vdbrad}
blender -b -noaudio --factory-startup --python "$here/blender_bridge.py" -- --out blender_bridge "$@"
test -s blender_bridge/baked.png
echo "blender_bridge: wrote blender_bridge/baked.png and blender_bridge/baked.blend" >&2
