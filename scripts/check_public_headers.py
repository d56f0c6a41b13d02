#!/usr/bin/env python3
"""Checks the public face: placedb/placedb.h and every placedb header it
includes (the headers `cmake --install` puts in place) name no other
library's types than the contract's: OpenCV's core module and Eigen (and the
C++ standard library). No JSON library, no pybind11, no ROS, no OpenCV
module beyond core, no internal placedb header.

    scripts/check_public_headers.py SRC_ROOT BUILD_INCLUDE_DIR

Prints the headers of the face and what is wrong; exits 1 when something is."""
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from check_layers import includes  # noqa: E402  (one reading of #include lines)

ALLOWED = re.compile(r"^(opencv2/core\.hpp|opencv2/core/types\.hpp|Eigen/(Core|Geometry)|"
                     r"[a-z_]+)$")  # the standard library's headers have no slash or dot
# Internal headers that must never be reached from the face.
INTERNAL = ("placedb/storage/database.h", "placedb/query/query.h",
            "placedb/session/storage_view.h", "placedb/util/thread_pool.h",
            "placedb/util/json_reader.h", "placedb/util/check.h")


def main():
    root, generated = sys.argv[1], sys.argv[2]
    seen, bad, todo = [], [], ["placedb/placedb.h"]
    while todo:
        header = todo.pop(0)
        if header in seen:
            continue
        seen.append(header)
        if header in INTERNAL:
            bad.append(f"{header} is internal but the face reaches it")
        path = os.path.join(root, header)
        if not os.path.exists(path):
            path = os.path.join(generated, header)
        for n, included in includes(path):
            if included.startswith("placedb/"):
                todo.append(included)
            elif not ALLOWED.match(included):
                bad.append(f"{header}:{n}: includes <{included}>, not part of the contract")
    for h in seen:
        print("public:", h)
    for b in bad:
        print("check_public_headers:", b)
    print(f"check_public_headers: {len(seen)} headers, {len(bad)} problems")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
