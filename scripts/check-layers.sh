#!/usr/bin/env bash
# Checks that vdbrad/ keeps its layers (docs/architecture.md): a file in vdbrad/FOLDER/ includes
# headers of its own folder and of the layers below only; folders on one level (glossy and cloud,
# mesh and surface, reference and render) do not include each other; only the hosts include the
# umbrella vdbrad.h; the installed headers (CMakeLists.txt's VDBRAD_PUBLIC_HEADERS) are vdbrad.h
# and exactly what it includes, directly or not. Prints each offence and exits 1.
#   check-layers.sh [ROOT]       check ROOT (default: this repository)
#   check-layers.sh --self-test  also prove that an upward include fails the check
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)

# Levels, bottom first; a folder may include a folder of a strictly lower level.
declare -A level=(
  [core]=0 [distribute]=1 [sweep]=2 [scene]=3 [glossy]=4 [cloud]=4
  [mesh]=5 [surface]=5 [reference]=6 [render]=6 [request]=7)

check() {
  local root=$1 bad=0 file folder line target
  for dir in "$root"/vdbrad/*/; do
    folder=$(basename "$dir")
    if [ -z "${level[$folder]+x}" ]; then
      echo "vdbrad/$folder/: a folder the layer table in scripts/check-layers.sh does not know"
      bad=1
      continue
    fi
  done
  for file in "$root"/vdbrad/*; do
    [ -f "$file" ] || continue
    case $(basename "$file") in vdbrad.h) ;; *) echo "${file#"$root"/}: files belong in a layer's folder"; bad=1 ;; esac
  done
  while IFS= read -r hit; do
    file=${hit%%:*}; rest=${hit#*:}; line=${rest%%:*}
    folder=$(echo "${file#"$root"/vdbrad/}" | cut -d/ -f1)
    target=$(echo "$rest" | sed -E 's/.*[<"]vdbrad\/([^">]*)[">].*/\1/')
    case $target in
      */*) ;;
      *) echo "${file#"$root"/}:$line: includes vdbrad/$target, outside the layers"; bad=1; continue ;;
    esac
    local to=${target%%/*}
    [ "$to" = "$folder" ] && continue
    if [ -z "${level[$to]+x}" ] || [ -z "${level[$folder]+x}" ] \
        || [ "${level[$to]}" -ge "${level[$folder]}" ]; then
      echo "${file#"$root"/}:$line: $folder (level ${level[$folder]:-?}) includes vdbrad/$target" \
           "(level ${level[$to]:-?}): only its own folder and lower levels"
      bad=1
    fi
  done < <(grep -rnE '^[[:space:]]*#[[:space:]]*include[[:space:]]*[<"]vdbrad/' "$root"/vdbrad/*/ || true)
  public_headers "$root" || bad=1
  return $bad
}

# The installed list against the closure of vdbrad.h's includes (a header missing from it breaks
# an installed build; one too many installs an internal header as if it were API).
public_headers() {
  local root=$1
  [ -f "$root/CMakeLists.txt" ] || return 0
  python3 - "$root" <<'PY'
import os, re, sys
root = sys.argv[1]
cmake = open(os.path.join(root, "CMakeLists.txt")).read()
m = re.search(r"set\(VDBRAD_PUBLIC_HEADERS(.*?)\)", cmake, re.S)
listed = set(m.group(1).split()) if m else set()
seen, stack = set(), ["vdbrad.h"]
while stack:
    h = stack.pop()
    if h in seen:
        continue
    seen.add(h)
    path = os.path.join(root, "vdbrad", h)
    if os.path.exists(path):
        stack += re.findall(r'#include "vdbrad/([^"]+)"', open(path).read())
seen.discard("core/Version.h")   # generated, installed from the build folder
bad = False
for h in sorted(seen - listed):
    print(f"CMakeLists.txt: vdbrad.h includes vdbrad/{h}, missing from VDBRAD_PUBLIC_HEADERS")
    bad = True
for h in sorted(listed - seen):
    print(f"CMakeLists.txt: VDBRAD_PUBLIC_HEADERS installs vdbrad/{h}, which vdbrad.h does not include")
    bad = True
sys.exit(1 if bad else 0)
PY
}

if [ "${1:-}" = "--self-test" ]; then
  check "$here" || { echo "check-layers: the tree fails the check"; exit 1; }
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  mkdir -p "$tmp/vdbrad/core" "$tmp/vdbrad/surface" "$tmp/vdbrad/glossy" "$tmp/vdbrad/cloud"
  printf '#include "vdbrad/core/Errors.h"\n' > "$tmp/vdbrad/surface/Down.h"
  check "$tmp" >/dev/null || { echo "check-layers: a downward include was refused"; exit 1; }
  printf '#include "vdbrad/surface/Down.h"\n' > "$tmp/vdbrad/core/Up.h"
  if check "$tmp" >/dev/null; then echo "check-layers: an upward include passed"; exit 1; fi
  rm "$tmp/vdbrad/core/Up.h"
  printf '#include "vdbrad/cloud/Side.h"\n' > "$tmp/vdbrad/glossy/Side.h"
  if check "$tmp" >/dev/null; then echo "check-layers: a sideways include passed"; exit 1; fi
  echo "check-layers: layers kept; upward and sideways includes are caught"
  exit 0
fi
check "${1:-$here}"
