#!/usr/bin/env bash
# Regenerates the command reference in docs/command-line.md (between its commands:begin and
# commands:end markers) from the tool's command table. (The name is historical: the reference
# used to live in the README.)
set -euo pipefail
cd "$(dirname "$0")/.."
tool=${1:-build/vdbrad}
python3 - "$tool" <<'PY'
import subprocess, sys
ref = subprocess.run([sys.argv[1], "help", "--markdown"], check=True, capture_output=True, text=True).stdout
begin = "<!-- commands:begin (vdbrad help --markdown) -->\n"
end = "<!-- commands:end -->"
s = open("docs/command-line.md").read()
b, e = s.index(begin) + len(begin), s.index(end)
open("docs/command-line.md", "w").write(s[:b] + ref + s[e:])
PY
