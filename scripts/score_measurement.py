"""Score measured cracks against the simulator's truth.

    score_measurement.py FLIGHT_DIR RUN_DIR [FLIGHT_DIR RUN_DIR ...]

Each candidate is matched to the truth crack nearest its position (within
0.3 m of the crack's centre line); a crack's candidate is the one with the
most frames. For each crack found, from its candidate's best view:

- width: `max_width_mm` against the crack's true widest, where the best view
  shows the whole crack (not cut by the image border, so its widest point is
  in view), banded by the crack's true width in pixels in that view;
- condition state: the candidate's against truth's (one without a state
  counts as wrong);
- length: along the trace (`length_m`) and the best box's diagonal on the
  surface (its pixels times the view's GSD), against the true length, for
  best views not cut by the border; and `length_m` for every candidate
  whose trace had each end seen inside a view (`measured`), long cracks no
  frame holds whole among them.

Prints one JSON object (the per-crack figures and their summaries).
"""

import json
import math
import statistics
import sys
from pathlib import Path

MATCH_M = 0.3
STATES = {"good": 1, "fair": 2, "poor": 3, "severe": 4}


def samples(crack, per_segment=10):
    points = []
    for line in crack["lines"]:
        for a, b in zip(line, line[1:]):
            for k in range(per_segment):
                s = k / per_segment
                points.append([a[i] + (b[i] - a[i]) * s for i in range(3)])
        points.append(line[-1])
    return points


def nearest_crack(cracks, p):
    best = None
    for c in cracks:
        d = min(math.dist(q, p) for q in c["_samples"])
        if d <= MATCH_M and (best is None or d < best[0]):
            best = (d, c)
    return best and best[1]


def band(px):
    if px >= 2.0:
        return "2 px or more"
    if px >= 0.5:
        return "0.5 to 2 px"
    return "under 0.5 px"


def score_flight(flight, run):
    truth = json.loads((flight / "truth.json").read_text())
    defects = json.loads((run / "defects.json").read_text())["defects"]
    cracks = truth["cracks"]
    for c in cracks:
        c["_samples"] = samples(c)
    frames = {f["time_ns"]: f for f in truth["frames"]}
    on = {}
    for d in defects:
        c = nearest_crack(cracks, d["position"])
        if c is not None:
            on.setdefault(c["id"], []).append(d)
    by_id = {c["id"]: c for c in cracks}
    rows = []
    for cid, candidates in sorted(on.items()):
        d = max(candidates, key=lambda d: d["frames"])
        c = by_id[cid]
        best = d["best"]
        seen = [v for v in frames[best["time_ns"]]["cracks"] if v["id"] == cid]
        width_px = seen[0].get("width_px") if seen else None
        width = d.get("width") or {}
        x0, y0, x1, y1 = best["bbox"]
        box_m = math.hypot(x1 - x0, y1 - y0) * best["gsd_mm"] / 1000.0
        rows.append(
            {
                "flight": flight.name,
                "crack": cid,
                "true_width_mm": c["width_mm"],
                "true_width_px": width_px,
                "true_state": c.get("condition_state"),
                "true_length_m": c["length_m"],
                "complete": not best["clipped"],
                "length_status": d["evidence"]["length"],
                "max_width_mm": width.get("max_mm"),
                "narrower_than_mm": width.get("narrower_than_mm"),
                "state": STATES.get(d.get("condition")),
                "length_m": d.get("length_m"),
                "box_length_m": box_m,
            }
        )
    return rows, len(defects), sum(len(v) for v in on.values())


def summary(values):
    if not values:
        return None
    q = statistics.quantiles(values, n=10) if len(values) > 1 else [values[0]] * 9
    return {
        "n": len(values),
        "median": statistics.median(values),
        "p10": q[0],
        "p90": q[8],
    }


def main(args):
    rows, candidates, on_cracks = [], 0, 0
    for flight, run in zip(args[::2], args[1::2]):
        r, n, m = score_flight(Path(flight), Path(run))
        rows += r
        candidates += n
        on_cracks += m
    widths = {}
    for r in rows:
        if r["complete"] and r["true_width_px"] is not None:
            b = band(r["true_width_px"])
            w = widths.setdefault(b, {"errors": [], "unmeasured": 0})
            if r["max_width_mm"] is None:
                w["unmeasured"] += 1
            else:
                w["errors"].append(abs(r["max_width_mm"] / r["true_width_mm"] - 1.0))
    states = [r for r in rows if r["true_state"] is not None]
    right = sum(1 for r in states if r["state"] == r["true_state"])
    lengths = [r for r in rows if r["complete"] and r["length_m"] is not None]
    out = {
        "cracks_found": len(rows),
        "candidates": candidates,
        "candidates_on_cracks": on_cracks,
        "width_error_by_band": {
            b: {"unmeasured": w["unmeasured"], "relative_error": summary(w["errors"])}
            for b, w in sorted(widths.items())
        },
        "condition_state": {
            "right": right,
            "of": len(states),
            "without_state": sum(1 for r in states if r["state"] is None),
        },
        "length_relative_error": {
            "along_trace": summary(
                [abs(r["length_m"] / r["true_length_m"] - 1) for r in lengths]
            ),
            "every_end_seen": summary(
                [
                    abs(r["length_m"] / r["true_length_m"] - 1)
                    for r in rows
                    if r["length_status"] == "measured"
                ]
            ),
            "box_diagonal": summary(
                [abs(r["box_length_m"] / r["true_length_m"] - 1) for r in lengths]
            ),
        },
        "cracks": rows,
    }
    json.dump(out, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    if len(sys.argv) < 3 or len(sys.argv) % 2 == 0:
        sys.exit("usage: score_measurement.py FLIGHT_DIR RUN_DIR [FLIGHT_DIR RUN_DIR ...]")
    main(sys.argv[1:])
