#!/usr/bin/env python3
"""Checks the house's layering: one library per folder of src/placedb, in the
order of the data flow, and every #include "placedb/..." of a library's code
points to its own folder or to a folder below it: no upward arrow, so no cycle
between libraries. Tests (*_test.cc) and the test helpers (util/testing.h,
ros/testbed.*, ros/system_testing.*) are not libraries and are not checked.

    scripts/check_layers.py [SRC_ROOT]     (default: src)

Prints every upward include and exits 1 when there is one."""
import os
import re
import sys

# The folders, from the ground up (the README's and ARCHITECTURE.md's order).
# Folders on one line share a floor: they may not include each other.
LAYERS = [
    ["util"],
    ["dataset"],
    ["dataset/bag"],  # ROS bags: rosbag_storage, for the clients only
    ["image"],
    ["feature/surf"],
    ["feature"],
    ["match"],
    ["storage"],
    ["retrieval"],
    ["query"],
    ["builder"],
    ["session"],
    ["eval"],
    ["distributed"],
    ["."],  # placedb/placedb.h: the public face
    ["cli"],
    ["exe", "ros", "python"],
]
FLOOR = {folder: i for i, floor in enumerate(LAYERS) for folder in floor}
NOT_LIBRARIES = ("util/testing.h", "ros/testbed.h", "ros/testbed.cc", "ros/system_testing.h",
                 "ros/system_testing.cc")


def includes(path):
    """(line number, included path) of every #include of a file, <...> or
    "..." (check_public_headers.py reads files the same way)."""
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            m = re.match(r'\s*#\s*include\s*[<"]([^>"]+)[>"]', line)
            if m:
                yield n, m.group(1)


def folder_of(path):
    d = os.path.dirname(path)
    return d if d else "."


def main():
    root = os.path.join(sys.argv[1] if len(sys.argv) > 1 else "src", "placedb")
    bad = []
    checked = 0
    for dirpath, _, files in os.walk(root):
        for name in sorted(files):
            if not name.endswith((".h", ".cc")) or name.endswith("_test.cc"):
                continue
            rel = os.path.relpath(os.path.join(dirpath, name), root)
            if rel in NOT_LIBRARIES:
                continue
            here = folder_of(rel)
            if here not in FLOOR:
                bad.append(f"{rel}: its folder {here}/ is not in the layer list")
                continue
            checked += 1
            for n, included in includes(os.path.join(dirpath, name)):
                if not included.startswith("placedb/"):
                    continue
                target = included[len("placedb/"):]
                there = folder_of(target)
                if target == "util/version.h" or there == here:
                    continue  # generated into util/; the same library
                if there not in FLOOR:
                    bad.append(f"{rel}:{n}: includes {target}, outside the layer list")
                elif FLOOR[there] >= FLOOR[here]:
                    bad.append(f"{rel}:{n}: {here}/ includes {target} ({there}/ is "
                               f"{'on the same floor' if FLOOR[there] == FLOOR[here] else 'above'})")
    for b in bad:
        print("check_layers:", b)
    print(f"check_layers: {checked} files, {len(bad)} upward or sideways includes")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
