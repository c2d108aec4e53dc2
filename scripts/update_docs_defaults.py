#!/usr/bin/python3
"""Rewrites the generated defaults tables in docs/*.md from the built binary. A block is
    <!-- generated: sonicboom config --markdown SECTIONS -->
    ...table...
    <!-- end generated -->
and its body becomes the output of `sonicboom config --markdown SECTIONS` (the defaults, as the
config structs' Serialize visitor writes them). CliTest.DocsDefaultsTablesAreCurrent fails when a
block is stale. Usage: /usr/bin/python3 scripts/update_docs_defaults.py [BIN]"""
import glob
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = sys.argv[1] if len(sys.argv) > 1 else os.environ.get(
    "SONICBOOM_BIN", os.path.join(ROOT, "build", "bin", "sonicboom"))
BLOCK = re.compile(r"(<!-- generated: sonicboom config --markdown (\S+) -->\n)(.*?)(<!-- end generated -->)",
                   re.S)


def table(sections):
    return subprocess.run([BIN, "config", "--markdown", sections], check=True,
                          capture_output=True, text=True).stdout


for path in sorted(glob.glob(os.path.join(ROOT, "docs", "*.md"))):
    text = open(path).read()
    new = BLOCK.sub(lambda m: m.group(1) + table(m.group(2)) + m.group(4), text)
    if new != text:
        open(path, "w").write(new)
        print("rewrote", os.path.relpath(path, ROOT))
