#!/usr/bin/env python3
"""docs/cli.md against the program: every option that `rayscan COMMAND --help` prints must be named
in that command's section, and each default and range that --help prints must stand on a line of
that section (or of the shared-options section's row naming the command) that names the option.
Usage: check_cli_reference.py RAYSCAN CLI_MD; exit 0 when all are there, 1 listing what is not."""
import re, subprocess, sys

rayscan, md_path = sys.argv[1], sys.argv[2]
md = open(md_path, encoding="utf-8").read()

def section(title):
    """Text of the '## `rayscan TITLE`' section, up to the next '## ' heading."""
    m = re.search(r"^## `rayscan " + re.escape(title) + r"`\n(.*?)(?=^## |\Z)", md, re.S | re.M)
    if not m:
        sys.exit(f"no section for {title}")
    return m.group(1)

# command -> the section that documents it (solar position lives in the solar section).
commands = {(): "__top__", ("render",): "render", ("visibility",): "visibility", ("solar",): "solar",
            ("solar", "position"): "solar", ("query",): "query", ("index",): "index", ("info",): "info",
            ("translate",): "translate", ("compare",): "compare", ("db", "import"): "db import",
            ("version",): "version"}
# the top-level options: `rayscan --version` is in the version section
top_section = section("version") + md.split("\n## ")[0]

failures, total = [], 0
for cmd, sec in commands.items():
    out = subprocess.run([rayscan, *cmd, "--help"], capture_output=True, text=True, check=True).stdout
    # option lines of the "Options:" block: leading spaces, then -x,--name,... up to a space
    opts = set()
    for line in out.split("Options:", 1)[1].split("Subcommands:", 1)[0].splitlines():
        m = re.match(r"^  (-[^\s]+)", line)
        if m:
            for name in m.group(1).split(","):
                opts.add(name)
    opts -= {"-h", "--help"}
    text = top_section if sec == "__top__" else section(sec)
    for o in sorted(opts):
        total += 1
        if not re.search(r"(?<![\w-])" + re.escape(o) + r"(?![\w-])", text):
            failures.append(f"rayscan {' '.join(cmd) or '(top)'}: {o} not in section '{sec}'")
    print(f"rayscan {' '.join(cmd) or '(top)':16s} {len(opts):3d} options checked")

# Defaults and ranges: CLI11 prints them in the type column ("FLOAT:a finite number in [0, 1]=0.2",
# "UINT:UINT in [1 - 21]=21", "TEXT=2G"); each must appear on a line of the section naming the option.
def rows(text, name):
    return [l for l in text.splitlines() if re.search(r"(?<![\w-])" + re.escape(name) + r"(?![\w-])", l)]

def num(x):
    try:
        v = float(x)
    except ValueError:
        return [x]
    forms = {x, f"{v:g}", re.sub(r"e\+?0*", "e", f"{v:g}"), str(int(v)) if v.is_integer() and abs(v) < 1e15 else x}
    return sorted(forms)

m = re.search(r"^## Options several commands share\n(.*?)(?=^## )", md, re.S | re.M)
shared = m.group(1) if m else ""
value_failures = 0
for cmd, sec in commands.items():
    if not cmd:
        continue
    out = subprocess.run([rayscan, *cmd, "--help"], capture_output=True, text=True, check=True).stdout
    text = section(sec)
    body = out.split("Options:", 1)[1].split("Subcommands:", 1)[0]
    for m in re.finditer(r"^  (-[^\s]+) +(\S[^\n]*)$", body, re.M):
        names = [n for n in m.group(1).split(",") if n.startswith("--")]
        typ = m.group(2)
        # options of the shared table count with its row when that row names this command
        lines = sum((rows(text, n) for n in names), [])
        lines += [l for n in names for l in rows(shared, n) if "`" + " ".join(cmd) + "`" in l]
        want = []
        d = re.search(r"=(\S+)", typ.split("  ")[0])
        if d and not d.group(1).startswith("["):
            want.append(("default", num(d.group(1))))
        r = re.search(r"in [\[(]([-0-9.e+]+) *[-,] *([-0-9.e+]+)\]", typ)
        if r:
            want.append(("range low", num(r.group(1))))
            want.append(("range high", num(r.group(2))))
        for what, forms in want:
            if not any(any(f in l for f in forms) for l in lines):
                value_failures += 1
                failures.append(f"rayscan {' '.join(cmd)}: {names[0]} {what} {forms[0]} not on its rows")

for f in failures:
    print("MISSING", f)
print(f"{total} options, {len(failures) - value_failures} missing; {value_failures} defaults/ranges not found")
sys.exit(1 if failures else 0)
