#!/usr/bin/env python3
"""Writes the README's option tables from the library's option tables.

Usage: option_tables.py PLACEDB README.md          rewrite the tables
       option_tables.py PLACEDB README.md --check  exit 1 when they are stale

PLACEDB is the built binary (build/src/placedb/exe/placedb). Its `placedb
options --markdown` prints every option of every command from the tables the
library describes each options struct with (name, flag, Python keyword,
default, range, help). The README holds that output between
`<!-- placedb options -->` and `<!-- /placedb options -->`; the text around
it is left alone. `make readme-options` runs the rewrite, and the CTest
`readme_options_test` runs the check, so a changed option (a new one, another
default or range) fails the suite until the README says it.
"""
import os
import subprocess
import sys

BEGIN = "<!-- placedb options -->"
END = "<!-- /placedb options -->"


def main(argv):
    check = "--check" in argv
    args = [a for a in argv if a != "--check"]
    if len(args) != 2:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    placedb, readme = args
    tables = subprocess.run([placedb, "options", "--markdown"], check=True, capture_output=True,
                            text=True).stdout.strip("\n")
    with open(readme, encoding="utf-8") as f:
        text = f.read()
    if text.count(BEGIN) != 1 or text.count(END) != 1 or text.index(BEGIN) > text.index(END):
        print(f"option_tables: {readme} must hold one {BEGIN} ... {END} block", file=sys.stderr)
        return 1
    head, rest = text.split(BEGIN)
    old, tail = rest.split(END)
    new = f"{head}{BEGIN}\n{tables}\n{END}{tail}"
    if check:
        if new != text:
            old_lines = set(old.strip("\n").splitlines())
            new_lines = tables.splitlines()
            changed = [line for line in new_lines if line not in old_lines]
            print(f"option_tables: the option tables of {readme} are stale; rewrite them with\n"
                  f"  python3 scripts/option_tables.py {placedb} {readme}\n"
                  f"(or `make readme-options`). First of {len(changed)} new or changed lines:",
                  file=sys.stderr)
            for line in changed[:5]:
                print("  " + line, file=sys.stderr)
            return 1
        print(f"option_tables: {readme} is current ({len(tables.splitlines())} lines)")
        return 0
    if new != text:
        tmp = f"{readme}.tmp.{os.getpid()}"
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(new)
        os.replace(tmp, readme)
        print(f"option_tables: rewrote the option tables of {readme}")
    else:
        print(f"option_tables: {readme} was current")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
