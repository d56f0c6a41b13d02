#!/usr/bin/env python3
"""The "hard places" table of `make demo` (scripts/demo.sh, step 7): the
defaults of small frames, the whole-image channel and sequence evidence,
measured on data/rtabmap_loop at several frame sizes. Prints the table and,
with --readme FILE, writes it between the README's markers
<!-- make demo: hard places --> and <!-- /make demo -->.

Usage: hard_places.py DIR [--readme README.md]
DIR holds <size>.fast20.json, <size>.json (eval --sequence, the defaults),
<size>.len5.json (--sequence-length 5) and <size>.whole.json
(--whole-image-weight 10) for each size of DIR/sizes.txt."""
import json
import os
import sys


def load(path):
    with open(path) as f:
        return json.load(f)


def main():
    args = sys.argv[1:]
    readme = None
    if "--readme" in args:
        i = args.index("--readme")
        readme = args[i + 1]
        del args[i:i + 2]
    if len(args) != 1:
        sys.exit(__doc__)
    d = args[0]
    sizes = open(os.path.join(d, "sizes.txt")).read().split()
    rows = []
    for size in sizes:
        base = os.path.join(d, size)
        fast20, default, len5, whole = (load(base + s) for s in
                                        (".fast20.json", ".json", ".len5.json", ".whole.json"))
        single = default["single_frame"]
        rows.append([
            size,
            f"{fast20['single_frame']['recall_at_1']:.3f}",
            f"{single['recall_at_1']:.3f}",
            f"{whole['single_frame']['recall_at_1']:.3f}",
            f"{len5['recall_at_1']:.3f}",
            f"{default['recall_at_1']:.3f}",
            f"{single['average_precision']:.3f} / {default['precision_recall']['average_precision']:.3f}",
            f"{single['recall_at_full_precision']:.3f} / "
            f"{default['precision_recall']['recall_at_full_precision']:.3f}",
            f"{default['sequence']['feed_ms_mean']:.3f}",
        ])
    head = ["frame", "single R@1, FAST 20 on upscaled", "single R@1 (default: FAST 5)",
            "single R@1 + whole image (weight 10)", "sequence R@1, length 5",
            "sequence R@1 (default: length 10)", "PR AUC single / sequence",
            "R@P=1 single / sequence", "sequence ms per frame"]
    table = ["| " + " | ".join(head) + " |", "| " + " | ".join("---" for _ in head) + " |"]
    table += ["| " + " | ".join(r) + " |" for r in rows]
    text = "\n".join(table)
    print(text)
    if readme:
        with open(readme) as f:
            s = f.read()
        begin, end = "<!-- make demo: hard places -->", "<!-- /make demo -->"
        a = s.find(begin)
        b = s.find(end, a)
        if a < 0 or b < 0:
            sys.exit(f"hard_places: {readme} has no {begin} ... {end} block")
        s = s[:a + len(begin)] + "\n" + text + "\n" + s[b:]
        with open(readme, "w") as f:
            f.write(s)


if __name__ == "__main__":
    main()
