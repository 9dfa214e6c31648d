#!/usr/bin/env bash
# Regenerates the README's command reference from the tool's command table.
set -euo pipefail
cd "$(dirname "$0")/.."
tool=${1:-build/vdbrad}
python3 - "$tool" <<'PY'
import subprocess, sys
ref = subprocess.run([sys.argv[1], "help", "--markdown"], check=True, capture_output=True, text=True).stdout
begin = "<!-- commands:begin (vdbrad help --markdown) -->\n"
end = "<!-- commands:end -->"
s = open("README.md").read()
b, e = s.index(begin) + len(begin), s.index(end)
open("README.md", "w").write(s[:b] + ref + s[e:])
PY
