#!/usr/bin/env python3
"""Writes OUT/report.html from OUT/results.json (written by `placedb experiment`).

    make_report.py OUT

The page is self-contained: every chart (drawn with matplotlib) and every
picture (drawn by placedb: match pictures, crop illustrations, failed queries)
is embedded as a data: URI, so the folder's report.html opens offline, alone.
The charts are also left as PNGs in OUT/figures/.

Exit status: 0 done, 1 bad input (one line on stderr), 3 matplotlib missing.
"""
import base64
import html
import json
import math
import os
import sys

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:  # pragma: no cover - depends on the machine
    print("make_report: matplotlib is not installed (Debian: apt-get install python3-matplotlib)",
          file=sys.stderr)
    sys.exit(3)

FEATURE_COLORS = {"orb": "#1f77b4", "surf": "#d62728"}
DPI = 110


class BadInput(Exception):
    pass


def need(obj, key, kind, where):
    if not isinstance(obj, dict) or key not in obj or not isinstance(obj[key], kind):
        raise BadInput(f"{where}: '{key}' is missing or not a {kind.__name__ if isinstance(kind, type) else kind}")
    return obj[key]


def load(out):
    path = os.path.join(out, "results.json")
    try:
        with open(path, encoding="utf-8") as f:
            results = json.load(f)
    except OSError as e:
        raise BadInput(f"cannot read {path}: {e.strerror}")
    except ValueError as e:
        raise BadInput(f"{path} is not valid JSON: {e}")
    settings = need(results, "settings", list, path)
    if not settings:
        raise BadInput(f"{path} has no settings")
    for i, s in enumerate(settings):
        where = f"{path}: settings[{i}]"
        st = need(s, "setting", dict, where)
        for key, kind in (("name", str), ("label", str), ("features", str), ("crop", str),
                          ("resize", int), ("verify", bool)):
            need(st, key, kind, where + ".setting")
        ev = need(s, "eval", dict, where)
        for key in ("num_queries", "num_correct", "num_answerable"):
            need(ev, key, int, where + ".eval")
        need(ev, "queries", list, where + ".eval")
        need(ev, "latency_ms", dict, where + ".eval")
        need(ev, "precision_recall", dict, where + ".eval")
        need(ev, "database_bytes", dict, where + ".eval")
        need(s, "num_keyframes", int, where)
    return results


def short(st):
    r = "1" if st["resize"] == 1 else f"1/{st['resize']}"
    return (f"{st['features'].upper()} {st['crop']} {r}" + (" V" if st["verify"] else "")
            + (" S" if st.get("sequence") else "") + (" W" if st.get("whole_image") else ""))


def save(fig, out, name):
    os.makedirs(os.path.join(out, "figures"), exist_ok=True)
    path = os.path.join(out, "figures", name + ".png")
    fig.savefig(path, dpi=DPI, bbox_inches="tight")
    plt.close(fig)
    return path


def series_key(st):
    """A bar series: feature x verification x sequence x whole image."""
    return (st["features"], st["verify"], st.get("sequence", False), st.get("whole_image", False))


def series_label(key):
    feature, verify, sequence, whole = key
    return (f"{feature.upper()}, verification {'on' if verify else 'off'}"
            + (", sequence" if sequence else "") + (", whole image" if whole else ""))


def bar_groups(settings):
    """x groups: crop x resize in grid order; series: series_key."""
    groups, series = [], []
    for s in settings:
        st = s["setting"]
        g, k = (st["crop"], st["resize"]), series_key(st)
        if g not in groups:
            groups.append(g)
        if k not in series:
            series.append(k)
    return groups, series


def grouped_bars(ax, settings, value, ylabel, fmt="{:.2f}"):
    groups, series = bar_groups(settings)
    width = 0.8 / max(1, len(series))
    lookup = {((s["setting"]["crop"], s["setting"]["resize"]), series_key(s["setting"])): s
              for s in settings}
    for j, key in enumerate(series):
        feature, verify, sequence, whole = key
        xs, ys = [], []
        for i, g in enumerate(groups):
            s = lookup.get((g, key))
            if s is None:
                continue
            xs.append(i + (j - (len(series) - 1) / 2) * width)
            ys.append(value(s))
        bars = ax.bar(xs, ys, width * 0.95, color=FEATURE_COLORS.get(feature, "#777"),
                      alpha=1.0 if verify else 0.55,
                      hatch=("" if verify else "//") + ("o" if sequence else "") + ("." if whole else ""),
                      edgecolor="white", label=series_label(key))
        crowded = len(series) > 2
        for x, y in zip(xs, ys):
            ax.annotate(fmt.format(y), (x, y), ha="center", va="bottom", fontsize=6 if crowded else 7,
                        rotation=90 if crowded else 0, xytext=(0, 2), textcoords="offset points")
    ax.set_xticks(range(len(groups)))
    ax.set_xticklabels([f"{c}\n{'1' if r == 1 else '1/' + str(r)}" for c, r in groups])
    ax.set_ylabel(ylabel)
    ax.set_ylim(0, ax.get_ylim()[1] * 1.12)  # room for the labels
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8)


def fig_time(settings, out):
    # Fig. 8: elapsed time normalised to the full-size uncropped database of the
    # same feature and verification; Fig. 12: time per query per keyframe.
    base = {}
    for s in settings:
        st = s["setting"]
        if st["crop"] == "none" and st["resize"] == 1:
            base[series_key(st)] = s["eval"]["latency_ms"]["mean"]
    fallback = max(s["eval"]["latency_ms"]["mean"] for s in settings) or 1.0

    def normalised(s):
        st = s["setting"]
        b = base.get(series_key(st), fallback) or 1.0
        return s["eval"]["latency_ms"]["mean"] / b

    fig, axes = plt.subplots(1, 2, figsize=(13, 4.2))
    grouped_bars(axes[0], settings, normalised,
                 "time per query / uncropped full-size time" if base else "time / slowest")
    axes[0].set_title("Matching time, normalised (paper Fig. 8)")
    grouped_bars(axes[1], settings,
                 lambda s: 1000.0 * s["eval"]["latency_ms"]["mean"] / max(1, s["num_keyframes"]),
                 "microseconds per query per keyframe", "{:.1f}")
    axes[1].set_title("Matching time per database keyframe (paper Fig. 12)")
    return save(fig, out, "time")


def fig_correct(settings, out):
    fig, ax = plt.subplots(figsize=(13, 4.2))
    grouped_bars(ax, settings, lambda s: s["eval"]["num_correct"], "correct matches (rank 1)",
                 "{:.0f}")
    n = settings[0]["eval"]["num_queries"]
    ax.axhline(n, color="#444", lw=0.8, ls=":")
    ax.set_title(f"Correct matches of {n} validation queries (paper Figs. 9, 13)")
    return save(fig, out, "correct")


def fig_size(settings, out):
    dbs = {}
    for s in settings:
        st = s["setting"]
        dbs.setdefault(st["database"] if "database" in st else short(st), s)
    names = list(dbs)
    images = [dbs[n]["eval"]["database_bytes"].get("images", 0) / 1024 for n in names]
    features = [dbs[n]["eval"]["database_bytes"].get("features", 0) / 1024 for n in names]
    reduction = [100 * dbs[n]["eval"].get("reduction_vs_full", 0.0) for n in names]
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.2))
    xs = range(len(names))
    axes[0].bar(xs, images, color="#2ca02c", label="stored PNG images")
    axes[0].bar(xs, features, bottom=images, color="#9467bd", label="keypoints + descriptors")
    axes[0].set_ylabel("KiB")
    axes[0].set_title("Database size (paper Figs. 10, 11)")
    axes[1].bar(xs, reduction, color="#ff7f0e")
    for x, r in zip(xs, reduction):
        axes[1].annotate(f"{r:.1f}%", (x, r), ha="center", va="bottom", fontsize=7)
    axes[1].set_ylabel("% less image data than every frame whole")
    axes[1].set_title("Image store reduction")
    for ax in axes:
        ax.set_xticks(list(xs))
        ax.set_xticklabels([n.replace("_", "\n") for n in names], fontsize=7)
        ax.grid(axis="y", alpha=0.3)
    axes[0].legend(fontsize=8)
    return save(fig, out, "size")


def line_style(st):
    return dict(color=FEATURE_COLORS.get(st["features"], "#777"),
                ls="-" if st["verify"] else "--",
                marker={"none": "o", "chroma": "s"}.get(st["crop"], "^"),
                alpha={1: 1.0, 4: 0.7, 16: 0.45}.get(st["resize"], 0.8), markersize=3, lw=1.2)


def fig_recall_at_k(settings, out):
    fig, ax = plt.subplots(figsize=(8, 5))
    for s in settings:
        ev = s["eval"]
        ranks = [q.get("first_correct_rank", 0) for q in ev["queries"] if not q.get("unreadable")]
        kmax = max([10] + ranks)
        positives = max(1, ev["num_answerable"])
        ks = list(range(1, kmax + 1))
        ax.plot(ks, [sum(1 for r in ranks if 1 <= r <= k) / positives for k in ks],
                label=short(s["setting"]), **line_style(s["setting"]))
    ax.set_xlabel("k (keyframes returned)")
    ax.set_ylabel("recall@k")
    ax.set_ylim(0, 1.02)
    ax.set_title("Recall@k: a true keyframe among the first k")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    return save(fig, out, "recall_at_k")


def fig_pr(settings, out):
    fig, ax = plt.subplots(figsize=(8, 5))
    for s in settings:
        pr = s["eval"]["precision_recall"]
        curve = pr.get("curve", [])
        rs = [0.0] + [p["recall"] for p in curve]
        ps = [1.0] + [p["precision"] for p in curve]
        ax.plot(rs, ps, label=f"{short(s['setting'])} (AUC {pr.get('average_precision', 0):.2f})",
                drawstyle="steps-post", **line_style(s["setting"]))
    ax.set_xlabel("recall")
    ax.set_ylabel("precision")
    ax.set_xlim(0, 1.02)
    ax.set_ylim(0, 1.02)
    ax.set_title("Precision-recall over the decision threshold")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    return save(fig, out, "precision_recall")


def fig_latency(settings, out):
    fig, ax = plt.subplots(figsize=(13, 4.5))
    data = []
    for s in settings:
        ms = [q["result"]["times_ms"]["total"] for q in s["eval"]["queries"]
              if not q.get("unreadable") and isinstance(q.get("result"), dict)]
        data.append(ms or [0.0])
    ax.boxplot(data, showfliers=True, flierprops=dict(markersize=2))
    ax.set_xticks(range(1, len(settings) + 1))
    ax.set_xticklabels([short(s["setting"]) for s in settings], rotation=60, ha="right",
                       fontsize=7)
    if min(min(d) for d in data) > 0:
        ax.set_yscale("log")
    ax.set_ylabel("ms per query (extraction included)")
    ax.set_title("Latency distribution per setting")
    ax.grid(axis="y", alpha=0.3)
    return save(fig, out, "latency")


def fig_stages(settings, out):
    fig, ax = plt.subplots(figsize=(13, 4.2))
    xs = range(len(settings))
    bottom = [0.0] * len(settings)
    for stage, color in (("extract", "#8c564b"), ("match", "#17becf"), ("verify", "#bcbd22")):
        ys = [s["eval"].get("stage_ms", {}).get(stage, {}).get("mean", 0.0) for s in settings]
        ax.bar(xs, ys, bottom=bottom, color=color, label=stage)
        bottom = [b + y for b, y in zip(bottom, ys)]
    ax.set_xticks(list(xs))
    ax.set_xticklabels([short(s["setting"]) for s in settings], rotation=60, ha="right",
                       fontsize=7)
    ax.set_ylabel("mean ms per query")
    ax.set_title("Where the time goes: stages of a query")
    ax.legend(fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    return save(fig, out, "stages")


def text_picture(out, name, text):
    fig, ax = plt.subplots(figsize=(6, 1.2))
    ax.axis("off")
    ax.text(0.5, 0.5, text, ha="center", va="center", fontsize=11)
    return save(fig, out, name)


def data_uri(path):
    with open(path, "rb") as f:
        return "data:image/png;base64," + base64.b64encode(f.read()).decode("ascii")


def picture_path(out, rel):
    if not isinstance(rel, str) or rel.startswith("/") or ".." in rel.split("/"):
        raise BadInput(f"results.json names a picture outside the folder: {rel!r}")
    path = os.path.join(out, rel)
    if not os.path.isfile(path):
        raise BadInput(f"results.json names a picture that is missing: {path}")
    return path


def figure(fid, paths, caption):
    imgs = "\n".join(f'<img src="{data_uri(p)}" alt="{html.escape(caption)}">' for p in paths)
    return (f'<figure class="placedb-figure" id="{fid}">\n{imgs}\n'
            f"<figcaption>{caption}</figcaption>\n</figure>")


def table(settings):
    head = ("<tr><th>setting</th><th>keyframes</th><th>correct</th><th>answerable</th><th>recall@1</th>"
            "<th>recall@5</th><th>precision</th><th>PR AUC</th><th>ms/query (mean)</th>"
            "<th>p99 ms</th><th>images (B)</th><th>reduction</th></tr>")
    rows = []
    for s in settings:
        ev = s["eval"]
        pr = ev["precision_recall"]
        rows.append(
            f"<tr><td>{html.escape(s['setting']['label'])}</td><td>{s['num_keyframes']}</td>"
            f"<td>{ev['num_correct']}/{ev['num_queries']}</td><td>{ev['num_answerable']}</td>"
            f"<td>{ev.get('recall_at_1', 0):.3f}</td>"
            f"<td>{ev.get('recall_at_5', 0):.3f}</td>"
            f"<td>{pr.get('at_threshold', {}).get('precision', 0):.3f}</td>"
            f"<td>{pr.get('average_precision', 0):.3f}</td>"
            f"<td>{ev['latency_ms'].get('mean', 0):.2f}</td><td>{ev['latency_ms'].get('p99', 0):.2f}</td>"
            f"<td>{ev['database_bytes'].get('images', 0)}</td>"
            f"<td>{100 * ev.get('reduction_vs_full', 0):.1f}%</td></tr>")
    return f"<table>\n{head}\n" + "\n".join(rows) + "\n</table>"


CSS = """
body { font-family: sans-serif; margin: 1.5em auto; padding: 0 1.5em; max-width: 1400px; color: #222; }
h1 { font-size: 1.6em; } h2 { font-size: 1.25em; margin-top: 2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; font-size: 0.85em; }
td, th { border: 1px solid #ccc; padding: 3px 8px; text-align: right; }
td:first-child, th:first-child { text-align: left; }
figure { margin: 1.2em 0; } figure img { max-width: 100%; display: block; margin-bottom: 6px; }
figcaption { font-size: 0.9em; color: #444; max-width: 1100px; }
.meta { color: #555; font-size: 0.9em; }
"""


def main(argv):
    if len(argv) != 2:
        print("usage: make_report.py OUT (the folder placedb experiment wrote)", file=sys.stderr)
        return 1
    out = argv[1]
    results = load(out)
    settings = results["settings"]
    pictures = results.get("pictures", {}) if isinstance(results.get("pictures"), dict) else {}
    n = settings[0]["eval"]["num_queries"]
    db = results.get("database_frames", {})
    qf = results.get("query_frames", {})
    parts = []
    parts.append("<h1>placedb experiment report</h1>")
    parts.append(
        f'<p class="meta">Database: {html.escape(str(db.get("from", "?")))} '
        f'({db.get("count", "?")} frames). Queries: {html.escape(str(qf.get("from", "?")))}, '
        f'{n} validation queries (seed {results.get("eval", {}).get("seed", "?")}). '
        f'Ground truth: {html.escape(str(results.get("truth", "?")))}. '
        f"{len(settings)} settings. Every number and picture on this page was measured by the "
        f"run that wrote results.json in this folder.</p>")
    parts.append("<h2>All settings</h2>")
    parts.append(table(settings))

    parts.append("<h2>The paper's figures, measured</h2>")
    parts.append(figure("fig-time", [fig_time(settings, out)],
                        "Mean time per query (extraction, matching and verification) relative to "
                        "the full-size, uncropped database of the same feature and verification "
                        "(left, as the paper's Fig. 8), and per database keyframe (right, Fig. 12)."))
    parts.append(figure("fig-correct", [fig_correct(settings, out)],
                        "Queries whose best keyframe is a true match (Figs. 9 and 13)."))
    parts.append(figure("fig-size", [fig_size(settings, out)],
                        "Bytes of each database: stored PNGs and features (left), and the image "
                        "store's reduction against storing every database frame whole as PNG "
                        "(right; Figs. 10 and 11)."))

    matches = [m for m in pictures.get("matches", []) if isinstance(m, dict)]
    if matches:
        parts.append("<h2>Match pictures (paper Figs. 4-7)</h2>")
        by_query = {}
        for m in matches:
            by_query.setdefault(m.get("query_id"), []).append(m)
        for qid, ms in by_query.items():
            desc = "; ".join(
                f"{m.get('crop')}: keyframe {m.get('keyframe_id')} "
                f"({'correct' if m.get('correct') else 'wrong'}), {m.get('num_matches')} matches, "
                f"{m.get('num_inliers')} verified" +
                (f", {m.get('num_lost')} lost by cropping" if m.get("crop") == "none" and
                 any(x.get("crop") == "chroma" for x in ms) else "")
                for m in ms)
            parts.append(figure(
                f"fig-match-q{int(qid)}", [picture_path(out, m.get("file")) for m in ms],
                f"Query {int(qid)} beside the keyframe each database chose; green: verified "
                f"matches, amber: matches geometry rejected, red (uncropped): matches whose "
                f"keyframe point lies outside the crop the chroma database keeps (blue box). "
                f"{html.escape(desc)}."))

    crops = [c for c in pictures.get("crops", []) if isinstance(c, dict)]
    if crops:
        parts.append("<h2>Feature-rich cropping (paper Fig. 14)</h2>")
        for c in crops:
            counts = ", ".join(f"{x.get('channel')}: {x.get('fast_keypoints')}"
                               for x in c.get("candidates", []) if x.get("valid"))
            parts.append(figure(
                f"fig-crop-{int(c.get('frame_id', 0))}", [picture_path(out, c.get("file"))],
                f"Database frame {int(c.get('frame_id', 0))}: the region of the largest "
                f"concentration of each rg-chromaticity channel with its FAST corners ({counts}); "
                f"threshold {c.get('min_fast_keypoints')}; winner: {html.escape(str(c.get('winner')))}"
                f"{' (the whole image is kept)' if c.get('whole_image') else ''}. Right: the kept "
                f"region as stored at each resize, at its true pixel size."))

    parts.append("<h2>Beyond the paper</h2>")
    parts.append(figure("fig-recall-at-k", [fig_recall_at_k(settings, out)],
                        "Recall@k: the share of answerable queries with a true keyframe among the "
                        "first k ranked (solid: verified; dashed: not; circles: uncropped, "
                        "squares: chroma crop; fainter: smaller resize)."))
    parts.append(figure("fig-pr", [fig_pr(settings, out)],
                        "Precision-recall curves over the decision threshold, with their area "
                        "(average precision)."))
    parts.append(figure("fig-latency", [fig_latency(settings, out)],
                        "Distribution of the whole query time, per setting (box: quartiles; "
                        "whiskers: 1.5 IQR; dots: outliers)."))
    parts.append(figure("fig-stages", [fig_stages(settings, out)],
                        "Mean time of each stage of a query."))
    failures = [f for f in pictures.get("failures", []) if isinstance(f, dict)]
    setting = html.escape(str(pictures.get("failure_setting", "")))
    if failures:
        paths = [picture_path(out, f.get("file")) for f in failures]
        caption = (f"Failed queries of {setting}: the query, the wrong answer, and a true "
                   f"keyframe ({len(failures)} shown).")
    else:
        paths = [text_picture(out, "no_failures", f"No query failed in {setting}.")]
        caption = f"Failed queries of {setting}: none."
    parts.append(figure("fig-failures", paths, caption))

    page = ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<title>placedb experiment report</title>\n"
            f"<style>{CSS}</style>\n</head>\n<body>\n" + "\n".join(parts) + "\n</body>\n</html>\n")
    path = os.path.join(out, "report.html")
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(page)
    os.replace(tmp, path)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except BadInput as e:
        print(f"make_report: {e}", file=sys.stderr)
        sys.exit(1)
