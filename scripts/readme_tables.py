#!/usr/bin/env python3
"""Rewrites the speed tables of README.md from the results of one `make bench` run.

Usage: readme_tables.py OUT_DIR README.md

OUT_DIR holds match_bench.json and surf_bench.json (Google Benchmark), and
placedb_bench_orb.json / placedb_bench_surf.json (`placedb bench --json`), and
when present ros_bench.json and scale_bench.json (bench/ros_bench, bench/scale_bench). Each
table sits in the README between `<!-- make bench: NAME -->` and
`<!-- /make bench -->`; the text around it is left alone. The tables are also
printed, so the run's output shows them.
"""
import json
import os
import re
import sys


def load(path):
    with open(path) as f:
        return json.load(f)


def benchmarks(path):
    return [b for b in load(path)["benchmarks"] if b.get("run_type", "iteration") == "iteration"]


def ns_per_item(b):
    return 1e9 / b["items_per_second"]


def faster(ratio):
    return f"{ratio:.1f}× faster" if ratio >= 1 else f"{1 / ratio:.1f}× slower"


def kernel_table(match):
    hamming = [b for b in match if b["name"].startswith("BM_TwoNearestHamming") and "error_occurred" not in b]
    bf = next(b for b in match if b["name"].startswith("BM_BfMatcherKnnHamming"))
    bf_ns = ns_per_item(bf)
    rows = ["| Hamming kernel (ORB, 32 bytes) | ns per distance | vs BFMatcher |", "| --- | --- | --- |"]
    for b in hamming:
        ns = ns_per_item(b)
        rows.append(f"| {b.get('label', b['name'])} | {ns:.3f} | {faster(bf_ns / ns)} |")
    rows.append(f"| OpenCV `BFMatcher::knnMatch` | {bf_ns:.3f} | 1 |")
    l2 = [b for b in match if b["name"].startswith("BM_TwoNearestL2") and "error_occurred" not in b]
    if l2:
        rows += ["", "| L2 kernel (SURF) | dims | ns per distance |", "| --- | --- | --- |"]
        for b in l2:
            dims = b["name"].split("/")[1]
            rows.append(f"| {b.get('label', b['name'])} | {dims} | {ns_per_item(b):.3f} |")
    return "\n".join(rows)


def surf_table(surf):
    ms = {b["name"]: b["real_time"] for b in surf}  # the benchmarks report milliseconds
    rows = ["| feature (one thread) | 640×480 TUM frame, ms | graf1 800×640, ms |", "| --- | --- | --- |"]
    names = [("placedb SURF", "BM_Surf"), ("placedb SURF, plain x86-64 path", "BM_SurfPlain"),
             ("placedb SURF upright", "BM_SurfUpright"), ("OpenCV SIFT", "BM_Sift"),
             ("OpenCV ORB (500)", "BM_Orb")]
    for label, name in names:
        if f"{name}/0" in ms:
            rows.append(f"| {label} | {ms[f'{name}/0']:.1f} | {ms[f'{name}/1']:.1f} |")
    ratios = (f"SURF takes {ms['BM_Surf/0'] / ms['BM_Sift/0']:.2f}× SIFT's time on the 640×480 frame and "
              f"{ms['BM_Surf/1'] / ms['BM_Sift/1']:.2f}× on graf1")
    return "\n".join(rows) + "\n\n" + ratios + "."


def placedb_table(orb, surf):
    rows = ["| matching per query | ORB ms | vs BFMatcher | SURF ms | vs BFMatcher |",
            "| --- | --- | --- | --- | --- |"]

    def cell(j, key):
        return f"{j[key]:.2f}"

    rows.append(f"| placedb, 1 thread | {cell(orb, 'placedb_ms_per_query')} | "
                f"{faster(orb['speedup_vs_bfmatcher'])} | {cell(surf, 'placedb_ms_per_query')} | "
                f"{faster(surf['speedup_vs_bfmatcher'])} |")
    rows.append(f"| placedb, {orb['placedb_threads']} threads | {cell(orb, 'placedb_mt_ms_per_query')} | "
                f"{faster(orb['speedup_mt_vs_bfmatcher'])} | {cell(surf, 'placedb_mt_ms_per_query')} | "
                f"{faster(surf['speedup_mt_vs_bfmatcher'])} |")
    rows.append(f"| OpenCV `BFMatcher` loop, the same rules (the paper's method) | "
                f"{cell(orb, 'bfmatcher_ms_per_query')} | 1 | {cell(surf, 'bfmatcher_ms_per_query')} | 1 |")
    rows.append(f"| placedb match + verify, 1 thread | {cell(orb, 'placedb_verified_ms_per_query')} | | "
                f"{cell(surf, 'placedb_verified_ms_per_query')} | |")
    note = (f"{orb['num_keyframes']} keyframes, {orb['num_queries']} queries; ORB {orb['num_db_descriptors']} "
            f"descriptors ({orb['distance_kernel']} kernel), SURF {surf['num_db_descriptors']} "
            f"({surf['distance_kernel']}). Rankings that differ from BFMatcher's: "
            f"{orb['rankings_that_differ']} (ORB), {surf['rankings_that_differ']} (SURF). Extracting the "
            f"query's features takes a further {orb['extract_ms_per_query']:.1f} ms (ORB) and "
            f"{surf['extract_ms_per_query']:.1f} ms (SURF).")
    return "\n".join(rows) + "\n\n" + note


def ros_table(r):
    rows = ["| | ms per frame, p50 | p99 | frames / s | vs one worker | transport + voting, p50 / p99 ms |",
            "| --- | --- | --- | --- | --- | --- |"]
    for threads in ("1", "2"):
        s = r["single_ms"][threads]
        rows.append(f"| single process, {threads} thread{'s' if threads != '1' else ''} | {s['p50']:.1f} | "
                    f"{s['p99']:.1f} | {1000 / s['mean']:.1f} | | |")
    for w in r["ros"]:
        l, a = w["latency_ms"], w["added_ms"]
        rows.append(f"| ROS, {w['workers']} worker{'s' if w['workers'] > 1 else ''} | {l['p50']:.1f} | "
                    f"{l['p99']:.1f} | {w['fps']:.1f} | {w['fps_vs_one_worker']:.2f}× | "
                    f"{a['p50']:.2f} / {a['p99']:.2f} |")
    answered = ", ".join(f"{w['answered']}/{w['published']}" for w in r["ros"])
    counts = ", ".join(str(w["workers"]) for w in r["ros"])
    note = (f"{r['keyframes']} keyframes ({r['features']} ORB features), {r['frames']} frames, {r['cpus']} CPUs; "
            f"frames answered ({counts} workers): {answered}.")
    if r.get("bow"):
        s = r["bow_single_ms"]
        rows.append(f"| bag of words, single process, 1 thread | {s['p50']:.1f} | {s['p99']:.1f} | "
                    f"{1000 / s['mean']:.1f} | | |")
        for w in r["bow"]:
            l, a = w["latency_ms"], w["added_ms"]
            rows.append(f"| bag of words on ROS, {w['workers']} workers (two rounds) | {l['p50']:.1f} | "
                        f"{l['p99']:.1f} | {w['fps']:.1f} | | {a['p50']:.2f} / {a['p99']:.2f} |")
        same = ", ".join(f"{w['same_as_single_process']}/{w['published']}" for w in r["bow"])
        counts = ", ".join(str(w["workers"]) for w in r["bow"])
        note += (f" Bag of words (the same keyframes with a bag-of-words index, default options): answers equal "
                 f"to the single process's ({counts} workers): {same}; complete: "
                 + ", ".join(f"{w['complete']}/{w['published']}" for w in r["bow"]) + ".")
    return "\n".join(rows) + "\n\n" + note


def FaultText(run):
    """The pages a run's queries read from disk (major page faults), when the bench counted them."""
    f = run.get("faults")
    if not f:
        return ""
    text = (f"; {f['major_faults']} major page faults (pages read from disk) in "
            f"{f['queries_with_major_faults']} of its queries")
    if f["queries_with_major_faults"] > 0 and "p99_ms_without" in f:
        text += f", p99 of the others {f['p99_ms_without']:.2f} ms"
    return text


def SizeLabel(s):
    """A size's keyframes, and the features each keeps when the database keeps fewer than it extracts."""
    stored = s.get("stored_features", 0)
    return f"{s['keyframes']}, {stored} stored" if stored > 0 else f"{s['keyframes']}"


def WithoutTheChannel(modes, m):
    """The runs of `modes` that are run m without the whole-image channel (same mode and guided count, no deadline)."""
    return [b for b in modes if b["mode"] == m["mode"] and b["deadline_ms"] == 0
            and b.get("guided_candidates", 0) == m.get("guided_candidates", 0)
            and b.get("whole_image_weight", 0) == 0]


def scale_table(j):
    rows = ["| keyframes | search | queries | p50 ms | p99 ms | recall@1 | place recall@1 | keyframes examined | "
            "vs exhaustive |", "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for s in j["sizes"]:
        for m in s["modes"]:
            name = m["mode"]
            guided = m.get("guided_candidates", 0)
            if m["mode"] != "exhaustive" and guided != j.get("guided_candidates", 0):
                name += (f", unguided (all {j['bow_candidates']} matched)" if guided == 0
                         else f", {guided} matched after guided ranking")
            if m["deadline_ms"] > 0:
                name += f", deadline {m['deadline_ms']:g} ms"
            whole = m.get("whole_image_weight", 0) > 0
            if whole:
                name += f" + whole image (weight {m['whole_image_weight']:g}"
                name += (f", {m['whole_image_candidates']} candidates)"
                         if m["mode"] != "exhaustive" and m['whole_image_candidates'] > 0 else ")")
            if "vs_popcount_limit" in m:
                vs = f"{m['vs_popcount_limit']:.2f}× the popcount limit"
            elif "recall_points_vs_exhaustive" in m:
                vs = (f"{m['recall_points_vs_exhaustive']:+.1f} / {m['place_recall_points_vs_exhaustive']:+.1f} "
                      "points")
            else:
                vs = ""
            if "overshoot_p99_ms" in m:
                vs += f"; overshoot p99 {m['overshoot_p99_ms']:.2f} ms"
                if "overshoot_max_ms" in m:
                    vs += f", max {m['overshoot_max_ms']:.2f} ms, {m['late_queries']} of {m['queries']} late"
                # One candidate's work, from the same size's bow run: its match and verify time per
                # candidate examined.
                full = [b for b in s["modes"] if b["mode"] == m["mode"] and b["deadline_ms"] == 0
                        and b.get("guided_candidates", 0) == m.get("guided_candidates", 0)]
                if full and full[0]["examined_mean"] > 0:
                    st = full[0]["stage_ms_mean"]
                    vs += f" (one candidate's match + verify: {(st['match'] + st['verify']) / full[0]['examined_mean']:.2f} ms)"
            if whole:
                # What the channel adds: the same mode without it, same size.
                plain = WithoutTheChannel(s["modes"], m)
                if plain:
                    b = plain[0]
                    vs += (f"; vs {m['mode']} without it: recall@1 "
                           f"{100 * (m['recall_at_1'] - b['recall_at_1']):+.1f} points, p50 "
                           f"{m['latency_ms']['p50'] - b['latency_ms']['p50']:+.2f} ms, p99 "
                           f"{m['latency_ms']['p99'] - b['latency_ms']['p99']:+.2f} ms")
            if s.get("stored_features", 0) > 0:
                # What the budget costs: the same run on the same keyframes keeping every feature.
                main = [b for t in j["sizes"] if t["keyframes"] == s["keyframes"]
                        and t.get("stored_features", 0) == j.get("stored_features", 0) for b in t["modes"]
                        if b["mode"] == m["mode"] and b["deadline_ms"] == m["deadline_ms"]
                        and b.get("guided_candidates", 0) == m.get("guided_candidates", 0)
                        and b.get("whole_image_weight", 0) == m.get("whole_image_weight", 0)]
                if main:
                    b = main[0]
                    vs += (f"; vs every feature: recall@1 {100 * (m['recall_at_1'] - b['recall_at_1']):+.1f}, "
                           f"place {100 * (m['place_recall_at_1'] - b['place_recall_at_1']):+.1f} points, "
                           f"p99 {m['latency_ms']['p99'] - b['latency_ms']['p99']:+.2f} ms")
                if whole:
                    # Against every feature without the channel: the default options' answers.
                    plain = WithoutTheChannel([b for t in j["sizes"] if t["keyframes"] == s["keyframes"]
                                               and t.get("stored_features", 0) == j.get("stored_features", 0)
                                               for b in t["modes"]], m)
                    if plain:
                        b = plain[0]
                        vs += (f"; vs every feature without it: recall@1 "
                               f"{100 * (m['recall_at_1'] - b['recall_at_1']):+.1f}, place "
                               f"{100 * (m['place_recall_at_1'] - b['place_recall_at_1']):+.1f} points")
            if m.get("faults", {}).get("major_faults", 0) > 0:
                vs += FaultText(m)
            vs = vs.lstrip("; ")
            rows.append(f"| {SizeLabel(s)} | {name} | {m['queries']} | {m['latency_ms']['p50']:.2f} | "
                        f"{m['latency_ms']['p99']:.2f} | {m['recall_at_1']:.3f} | {m['place_recall_at_1']:.3f} | "
                        f"{m['examined_mean']:.0f} | {vs} |")
    rows += ["", "| keyframes | features (per keyframe) | build s | database MB | open ms, warm (cold) | "
             "resident after open MiB: private + file-backed | after the runs (queries) | "
             "verify s | popcount limit ms |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    memory_runs, partition_runs = [], []
    for s in j["sizes"]:
        cold = s.get("first_open_cold", False)
        first = f" ({s['first_open_ms']:.1f}{'' if cold else ', first'})" if "first_open_ms" in s else ""
        if "resident_after_open" in s:
            o, r = s["resident_after_open"], s["resident_after_runs"]
            after_open = f"{o['private_mib']:.0f} + {o['file_mib']:.0f}"
            after_runs = f"{r['private_mib']:.0f} + {r['file_mib']:.0f} ({s['runs_queries']})"
        else:
            after_open, after_runs = f"+{s['rss_increase_mib']:.0f} (RSS)", ""
        verify = f"{s['verify_ms'] / 1000:.1f}" if "verify_ms" in s else ""
        rows.append(f"| {SizeLabel(s)} | {s['features']} ({s['features_per_keyframe']:.0f}) | "
                    f"{s['build_seconds']:.0f} | {s['database_bytes'] / 1e6:.1f} | {s['open_ms']:.1f}{first} | "
                    f"{after_open} | {after_runs} | {verify} | {s['popcount_limit_ms']:.2f} |")
        for m in s.get("memory_runs", []):
            memory_runs.append((s, m))
        if "partition_run" in s:
            partition_runs.append((s["keyframes"], s["partition_run"]))
    for s, m in memory_runs:
        r = m["resident_increase"]
        limit = m.get("resident_limit_mb", 0)
        reads = ("the examined keyframes' features read from the file rather than mapped" if m.get("read_features")
                 else "the features mapped")
        if m["default_options"]:
            limit_text = f"with the default options: {reads}, as the keyframe file is " + (
                "above" if m.get("read_features") else "within") + " `read_features_above_mb`"
        elif limit > 0:
            limit_text = f"with `resident_limit_mb` {limit} and {reads}: `read_features_above_mb` 0"
        else:
            limit_text = f"without a resident limit and with {reads}: `read_features_above_mb` 0"
        by_file = m.get("resident_by_file_mib", {})
        files = ", ".join(f"{name.split('.')[0]} {mib:.0f}" for name, mib in sorted(by_file.items()))
        place = f", place recall@1 {m['place_recall_at_1']:.3f}" if "place_recall_at_1" in m else ""
        vs = ""
        if s.get("stored_features", 0) > 0:
            # The same queries on the same keyframes keeping every feature, the same options.
            # A run with the whole-image channel is compared with every feature's without it,
            # then with it at the same weight.
            def EveryFeature(weight):
                return [w for t in j["sizes"] if t["keyframes"] == s["keyframes"]
                        and t.get("stored_features", 0) == j.get("stored_features", 0)
                        for w in t.get("memory_runs", []) if w["default_options"] == m["default_options"]
                        and w.get("resident_limit_mb", 0) == m.get("resident_limit_mb", 0)
                        and w.get("whole_image_weight", 0) == weight and "place_recall_at_1" in w][:1]
            weight = m.get("whole_image_weight", 0)
            if weight > 0:
                against = ([(w, "every feature without the channel") for w in EveryFeature(0)]
                           + [(w, "every feature with it") for w in EveryFeature(weight)])
            else:
                against = [(w, "every feature") for w in EveryFeature(0)]
            parts = []
            for w, label in (against if "place_recall_at_1" in m else []):
                parts.append(f"{label}, the same queries: recall@1 "
                             f"{100 * (m['recall_at_1'] - w['recall_at_1']):+.1f}, place "
                             f"{100 * (m['place_recall_at_1'] - w['place_recall_at_1']):+.1f} points, p99 "
                             f"{m['latency_ms']['p99'] - w['latency_ms']['p99']:+.2f} ms")
            if parts:
                vs = " (" + "; ".join(parts) + ")"
        rows += ["", f"At {SizeLabel(s)} keyframes, a process of its own opened a session ({limit_text}) and asked "
                 f"{m['queries']} bag-of-words queries"
                 + (f" with whole-image scoring (weight {m['whole_image_weight']:g})"
                    if m.get("whole_image_weight", 0) > 0 else "") +
                 " (fresh views spread over the map): the session added "
                 f"**{r['private_mib']:.0f} MiB private + {r['file_mib']:.0f} MiB file-backed** resident memory"
                 + (f" (mapped and resident at the end, MiB: {files})" if files else "") +
                 f"; their latency p50 {m['latency_ms']['p50']:.2f} ms, p99 {m['latency_ms']['p99']:.2f} ms, "
                 f"recall@1 {m['recall_at_1']:.3f}{place}{vs}" + FaultText(m) + "."]
    for keyframes, p in partition_runs:
        w = p["workers"]
        files = max(x["file_mib"] for x in w)
        private = max(x["private_mib"] for x in w)
        rows += ["", "| keyframes | partitions (processes) | queries | answers equal to the whole map's | "
                 "p50 ms at the voter | p99 ms | recall@1 (whole map) | keyframes examined | "
                 "each worker: open ms, resident after the queries MiB (private + file-backed, the largest) |",
                 "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
                 f"| {keyframes} | {p['partitions']} | {p['queries']} | **{p['same_answers']} of {p['queries']}** | "
                 f"{p['latency_ms']['p50']:.2f} | {p['latency_ms']['p99']:.2f} | {p['recall_at_1']:.3f} "
                 f"({p['whole_recall_at_1']:.3f}) | {p['examined_mean']:.1f} | "
                 f"{max(x['open_ms'] for x in w):.1f}, {private:.0f} + {files:.0f} |"]
    note = (f"{j['sample_images']} sample images augmented; at most {j['features_per_frame']} ORB features per "
            f"frame (FAST threshold {j['fast_threshold']}); {j['cpus']} CPUs; queries on one thread, feature "
            f"extraction excluded; bow scores {j['bow_candidates']} candidates by bag of words and matches the "
            f"{j.get('guided_candidates', 0)} with the most guided matches in full (unguided: all of them). "
            "recall@1: the answer is the very "
            "keyframe the query was made from; place recall@1: a view of the same sample image. Exhaustive search "
            f"runs on {j['exhaustive_queries_above_1000']} of the queries above 1000 keyframes; \"vs exhaustive\" "
            "gives the difference in recall@1 / place recall@1 on those. Open: the best of 3 opens with the "
            "files in the page cache; in brackets the first open, with every file of the database dropped from "
            "the page cache first (posix_fadvise DONTNEED). Resident memory: what the open added to the "
            "process, private (RssAnon, the heap) and file-backed (RssFile, pages of the mapped files read so "
            "far); then the same after all the runs of the table (exhaustive search maps every page where the features are mapped). Verify: `placedb verify` (every byte). "
            "Popcount limit: "
            f"{j['ns_per_distance']:.3f} ns per distance ({j['hamming_kernel']} kernel, in cache) × query features × "
            "database features.")
    reading = [SizeLabel(s) for s in j["sizes"] if s.get("reads_features")]
    if reading:
        note += (f" In the rows of {' and of '.join(reading)} keyframes the sessions read the examined keyframes' features from the "
                 "file rather than mapping them (the default: the keyframe file is above `read_features_above_mb`, "
                 f"{j.get('read_features_above_mb', 1024)} MiB), so exhaustive search there reads every keyframe rather than mapping it.")
    if j.get("compare_stored"):
        track = j.get("track_neighbours", 0)
        ranked = (f"those matched in the {track} nearest keyframes first (`track_neighbours`), the strongest "
                  "spread over the image" if track > 0 else "the strongest spread over the image")
        note += (" \"N stored\": a database of the same keyframes keeping at most N features per keyframe "
                 f"(`stored_features`: {ranked}), with the same queries, which keep "
                 "all their features; bow runs only (with and without the whole-image channel).")
    return "\n".join(rows) + "\n\n" + note


def sequence_table(runs):
    """sequence_bench: the sequence step and the whole-image comparison per map size."""
    ms = {b["name"]: b["real_time"] for b in runs}  # the benchmark's unit: ms
    rows = ["| keyframes | sequence step, ranked lists (ms) | over the whole map (ms) | "
            "HOG rows, 512 values (ms) | thumbnail rows, 768 values (ms) |",
            "| --- | --- | --- | --- | --- |"]
    for n in (10000, 100000):
        rows.append(f"| {n} | {ms[f'BM_SequenceFeed/{n}/0']:.3f} | {ms[f'BM_SequenceFeed/{n}/1']:.3f} | "
                    f"{ms[f'BM_HogSimilarities/{n}/512']:.3f} | {ms[f'BM_HogSimilarities/{n}/768']:.3f} |")
    return "\n".join(rows)


def main():
    out, readme = sys.argv[1], sys.argv[2]
    tables = {}
    if os.path.exists(os.path.join(out, "placedb_bench_orb.json")):
        tables["placedb"] = placedb_table(load(os.path.join(out, "placedb_bench_orb.json")),
                                          load(os.path.join(out, "placedb_bench_surf.json")))
    if os.path.exists(os.path.join(out, "match_bench.json")):
        tables["kernels"] = kernel_table(benchmarks(os.path.join(out, "match_bench.json")))
    if os.path.exists(os.path.join(out, "surf_bench.json")):
        tables["surf"] = surf_table(benchmarks(os.path.join(out, "surf_bench.json")))
    if os.path.exists(os.path.join(out, "sequence_bench.json")):
        tables["sequence"] = sequence_table(benchmarks(os.path.join(out, "sequence_bench.json")))
    if not tables:
        sys.exit(f"readme_tables: no benchmark results in {out}")
    if os.path.exists(os.path.join(out, "ros_bench.json")):
        tables["ros"] = ros_table(load(os.path.join(out, "ros_bench.json")))
    if os.path.exists(os.path.join(out, "scale_bench.json")):
        tables["scale"] = scale_table(load(os.path.join(out, "scale_bench.json")))
    text = open(readme).read()
    for name, table in tables.items():
        print(f"--- {name}\n{table}\n")
        pattern = re.compile(r"(<!-- make bench: %s -->\n).*?(<!-- /make bench -->)" % re.escape(name), re.S)
        if not pattern.search(text):
            sys.exit(f"readme_tables: {readme} has no '<!-- make bench: {name} -->' block")
        text = pattern.sub(lambda m: m.group(1) + table + "\n" + m.group(2), text)
    with open(readme, "w") as f:
        f.write(text)
    print(f"readme_tables: wrote the speed tables of {readme}")


if __name__ == "__main__":
    main()
