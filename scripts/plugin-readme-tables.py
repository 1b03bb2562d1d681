#!/usr/bin/env python3
"""Prints Markdown parameter tables from `spangle plugins`, for plugins/*/README.md.

    python3 scripts/plugin-readme-tables.py build/spangle smooth
"""
import re
import subprocess
import sys

out = subprocess.run([sys.argv[1], "plugins"], capture_output=True, text=True).stdout
want = sys.argv[2]
current = None
for line in out.splitlines():
    m = re.match(r"^(\w+) \(", line)
    if m:
        current = m.group(1)
        continue
    if current != want:
        continue
    m = re.match(r"^  model (\w+): (.*)$", line)
    if m:
        print(f"\n### `{m.group(1)}`: {m.group(2)}\n")
        print("| parameter | type | default | range | meaning |")
        print("|---|---|---|---|---|")
        continue
    m = re.match(r"^    (\w+)\s+(\w+)\s+= (.+?)\s+(in \[[^\]]*\]|one of \S+|any name)?\s\s(.*)$", line)
    if m:
        rng = (m.group(4) or "").replace("in ", "").replace("one of ", "").replace("|", ", ")
        print(f"| `{m.group(1)}` | {m.group(2)} | `{m.group(3).strip()}` | {rng} | {m.group(5).strip()} |")
