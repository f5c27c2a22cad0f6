"""Every tile against the best views of each patch, scored against the
simulator's truth (scripts/bench-best-views runs it).

    score_best_views.py FLIGHT ALL_TILES_RUN BEST_VIEWS_RUN [FLIGHT ALL BEST ...]

For each flight and each run: `postflight detect`'s wall time (its
`detect.wall`), the estimate it printed and detect.json's own seconds, the
tiles run and skipped; recall (the cracks the flight shows, truth's or
either run's finds, with a candidate on them, scripts/score_measurement.py's
matching; and against the cracks truth lists in at least one frame, and
at least two) and precision (candidates on a truth crack); the widths of the cracks both runs found
(median `max_width_mm`, and the median error against truth's widest).

Two rules say when a candidate is on a crack. In space (score_measurement's,
`recall`, `precision`): its place within 0.3 m of the crack. In the image
(`image_rule`): one of its views' boxes on the crack where truth draws it
in that frame (its box, 4 px of slack for hairline boxes). The first also
takes a dark edge of the structure near a crack for the crack; the
second does not (a box on the edge is not on the crack's pixels).

Prints one JSON object, by the best views run's directory name.
"""

import json
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from score_measurement import score_flight  # noqa: E402


def detect_figures(run):
    summary = json.loads((run / "detect.json").read_text())
    start, end = (float(x) for x in (run / "detect.wall").read_text().split())
    return {
        "wall_s": end - start,
        "detect_s": summary["seconds"],
        "estimate_s": summary.get("estimate_s"),
        "tiles_run": summary["tiles_run"],
        "tiles_skipped": summary["tiles_skipped"],
        "frames_run": summary["frames_run"],
        "frames": summary["frames"],
    }


def crack_figures(flight, run):
    rows, candidates, on_cracks = score_flight(flight, run)
    return rows, {
        "candidates": candidates,
        "candidates_on_cracks": on_cracks,
        "cracks_found": len(rows),
        "precision": on_cracks / max(candidates, 1),
    }


SLACK_PX = 4.0


def image_rule(truth, run):
    """Recall and precision by the image rule: the cracks with a candidate
    on them (a view's box overlapping truth's box of the crack in that
    frame), of those truth draws in some frame; candidates on a crack."""
    frames = {f["time_ns"]: f for f in truth["frames"]}
    drawn = {v["id"] for f in truth["frames"] for v in f["cracks"]}
    defects = json.loads((run / "defects.json").read_text())["defects"]

    def overlaps(a, b):
        return (a[0] - SLACK_PX < b[2] and b[0] - SLACK_PX < a[2]
                and a[1] - SLACK_PX < b[3] and b[1] - SLACK_PX < a[3])

    found, on = set(), 0
    for d in defects:
        cracks = {
            v["id"]
            for view in d.get("views") or [d["best"]]
            for v in frames.get(view["time_ns"], {"cracks": []})["cracks"]
            if overlaps(view["bbox"], v["bbox"])
        }
        found |= cracks
        on += bool(cracks)
    return {
        "cracks_found": len(found),
        "cracks_drawn": len(drawn),
        "recall": len(found) / max(len(drawn), 1),
        "candidates_on_cracks": on,
        "precision": on / max(len(defects), 1),
    }


def main(args):
    out = {}
    for flight, every, best in zip(args[::3], args[1::3], args[2::3]):
        flight = Path(flight)
        truth = json.loads((flight / "truth.json").read_text())
        runs = {}
        rows = {}
        for name, run in (("every_tile", Path(every)), ("best_views", Path(best))):
            rows[name], cracks = crack_figures(flight, run)
            runs[name] = {**detect_figures(run), **cracks}
        # The cracks the flight shows: those truth lists in some frame, and
        # any either run found (truth lists a view where the crack shows
        # through the lens's spread; the detector may find fainter ones).
        views = {}
        for f in truth["frames"]:
            for v in f["cracks"]:
                views[v["id"]] = views.get(v["id"], 0) + 1
        seen = set(views) | {r["crack"] for name in rows for r in rows[name]}
        for name in runs:
            runs[name]["cracks_shown"] = len(seen)
            runs[name]["recall"] = runs[name]["cracks_found"] / max(len(seen), 1)
            # Against the cracks truth lists in at least 1 and 2 frames.
            found = {r["crack"] for r in rows[name]}
            runs[name]["recall_by_truth_views"] = {
                f"{m}+": [len(found & {c for c, n in views.items() if n >= m}),
                          sum(1 for n in views.values() if n >= m)]
                for m in (1, 2)
            }
        for name, run in (("every_tile", Path(every)), ("best_views", Path(best))):
            runs[name]["image_rule"] = image_rule(truth, run)
        both = {r["crack"] for r in rows["every_tile"]} & {r["crack"] for r in rows["best_views"]}
        for name in runs:
            measured = [r for r in rows[name] if r["crack"] in both and r["max_width_mm"]]
            runs[name]["width_median_mm"] = statistics.median(r["max_width_mm"] for r in measured) if measured else None
            runs[name]["width_error_median"] = (
                statistics.median(abs(r["max_width_mm"] / r["true_width_mm"] - 1) for r in measured)
                if measured
                else None
            )
        e, b = runs["every_tile"], runs["best_views"]
        out[Path(best).name] = {
            **runs,
            "time_ratio": b["wall_s"] / e["wall_s"],
            "recall_points": 100 * (b["recall"] - e["recall"]),
            "precision_points": 100 * (b["precision"] - e["precision"]),
            "image_rule_recall_points": 100 * (b["image_rule"]["recall"] - e["image_rule"]["recall"]),
            "image_rule_precision_points": 100
            * (b["image_rule"]["precision"] - e["image_rule"]["precision"]),
            "width_median_change": (b["width_median_mm"] / e["width_median_mm"] - 1)
            if e["width_median_mm"] and b["width_median_mm"]
            else None,
            "estimate_over_detect": {
                name: runs[name]["estimate_s"] / runs[name]["detect_s"]
                for name in runs
                if runs[name]["estimate_s"]
            },
        }
    json.dump(out, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    if len(sys.argv) < 4 or (len(sys.argv) - 1) % 3:
        sys.exit("usage: score_best_views.py FLIGHT ALL_TILES_RUN BEST_VIEWS_RUN [...]")
    main(sys.argv[1:])
