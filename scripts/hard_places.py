#!/usr/bin/env python3
"""The tables of `make demo` (scripts/demo.sh) that choose defaults.

"hard places" (step 7): small frames, the whole-image channel and sequence
evidence, measured on data/rtabmap_loop at several frame sizes. DIR holds
<size>.fast20.json, <size>.json (eval --sequence, the defaults),
<size>.len5.json (--sequence-length 5) and <size>.local.json (local
features alone: the whole-image channel off in the frame and the sequence)
for each size of DIR/sizes.txt.

"places that change" (step 7b, --change CHANGE_DIR): each channel of the
whole-image descriptor and the sequence search, alone and together, on the
Nordland slice (summer map, winter queries) and on data/rtabmap_loop. CHANGE_DIR
holds <data>.<setting>.json for each data set and setting of SETTINGS below.

Prints the tables and, with --readme FILE, writes each between the README's
markers <!-- make demo: NAME --> and <!-- /make demo -->.

Usage: hard_places.py DIR [--change CHANGE_DIR] [--readme README.md]"""
import json
import os
import sys


def load(path):
    with open(path) as f:
        return json.load(f)


def main():
    args = sys.argv[1:]
    readme = change = None
    for flag in ("--readme", "--change"):
        if flag in args:
            i = args.index(flag)
            if i + 1 >= len(args):
                sys.exit(__doc__)
            if flag == "--readme":
                readme = args[i + 1]
            else:
                change = args[i + 1]
            del args[i:i + 2]
    if len(args) != 1:
        sys.exit(__doc__)
    d = args[0]
    sizes = open(os.path.join(d, "sizes.txt")).read().split()
    rows = []
    for size in sizes:
        base = os.path.join(d, size)
        fast20, default, len5, local = (load(base + s) for s in
                                        (".fast20.json", ".json", ".len5.json", ".local.json"))
        single = default["single_frame"]
        rows.append([
            size,
            f"{fast20['single_frame']['recall_at_1']:.3f}",
            f"{single['recall_at_1']:.3f}",
            f"{local['single_frame']['recall_at_1']:.3f} / {local['recall_at_1']:.3f}",
            f"{len5['recall_at_1']:.3f}",
            f"{default['recall_at_1']:.3f}",
            f"{single['average_precision']:.3f} / {default['precision_recall']['average_precision']:.3f}",
            f"{single['recall_at_full_precision']:.3f} / "
            f"{default['precision_recall']['recall_at_full_precision']:.3f}",
            f"{default['sequence']['feed_ms_mean']:.3f}",
        ])
    head = ["frame", "single R@1, FAST 20 on upscaled", "single R@1 (default: FAST 5)",
            "local features alone: single / sequence R@1", "sequence R@1, length 5",
            "sequence R@1 (default: length 15)", "PR AUC single / sequence",
            "R@P=1 single / sequence", "sequence ms per frame"]
    table = ["| " + " | ".join(head) + " |", "| " + " | ".join("---" for _ in head) + " |"]
    table += ["| " + " | ".join(r) + " |" for r in rows]
    tables = {"hard places": "\n".join(table)}
    if change:
        tables["places that change"] = change_table(change)
    for name, text in tables.items():
        print(text)
        if readme:
            write_block(readme, name, text)


def write_block(readme, name, text):
    """Writes `text` between <!-- make demo: NAME --> and the next <!-- /make demo -->."""
    with open(readme) as f:
        s = f.read()
    begin, end = f"<!-- make demo: {name} -->", "<!-- /make demo -->"
    a = s.find(begin)
    b = s.find(end, a)
    if a < 0 or b < 0:
        sys.exit(f"hard_places: {readme} has no {begin} ... {end} block")
    s = s[:a + len(begin)] + "\n" + text + "\n" + s[b:]
    with open(readme, "w") as f:
        f.write(s)


# The settings of step 7b: file suffix, what the row says. Each eval JSON
# has the single-frame answers and the sequence's (eval --sequence).
SETTINGS = [
    ("default", "**the defaults**: local features + the HOG channel (10 a deviation above 3), "
                "the sequence over the whole map"),
    ("local", "local features alone (`--whole-image-weight 0 --whole-image-candidates 0 "
              "--sequence-whole-image-weight 0`)"),
    ("whole", "the whole image first (`--whole-image-weight 1000 --whole-image-floor 0`)"),
    ("lists", "the sequence over each frame's ranked list only (`--sequence-whole-image-weight 0`)"),
    ("thumb", "the thumbnail channel instead of HOG (`--whole-image-kind thumbnail` at build)"),
    ("velocities", "SeqSLAM's velocities (`--sequence-min/max-velocity 0.8/1.2`, 5 steps)"),
    ("clahe", "local features of CLAHE-equalised frames (`--clahe true` at build)"),
]
DATASETS = [("nordland", "Nordland slice, winter vs summer"), ("rtabmap", "rtabmap_loop 41-84 vs 1-40")]


def change_table(d):
    head = ["setting"]
    for _, label in DATASETS:
        head += [f"{label}: single R@1", "sequence R@1", "PR AUC single / sequence"]
    rows = []
    for suffix, label in SETTINGS:
        row = [label]
        for name, _ in DATASETS:
            e = load(os.path.join(d, f"{name}.{suffix}.json"))
            single = e["single_frame"]
            row += [f"{single['recall_at_1']:.3f}", f"{e['recall_at_1']:.3f}",
                    f"{single['average_precision']:.3f} / "
                    f"{e['precision_recall']['average_precision']:.3f}"]
        rows.append(row)
    # The classic methods on the same frames (eval --baseline both, with the
    # first setting): HOG answers single frames, SeqSLAM sequences.
    for key, label, column in (("hog", "HOG of the whole frame (classic: `eval --baseline hog`)", 0),
                               ("seqslam", "SeqSLAM, 10 frames (classic: `eval --baseline seqslam`)", 1)):
        row = [label]
        for name, _ in DATASETS:
            b = load(os.path.join(d, f"{name}.{SETTINGS[0][0]}.json"))["baselines"][key]
            recall, auc = f"{b['recall_at_1']:.3f}", f"{b['average_precision']:.3f}"
            if column == 0:
                row += [recall, "", f"{auc} / -"]
            else:
                row += ["", recall, f"- / {auc}"]
        rows.append(row)
    table = ["| " + " | ".join(head) + " |", "| " + " | ".join("---" for _ in head) + " |"]
    table += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(table)

if __name__ == "__main__":
    main()
