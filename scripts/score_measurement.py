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
  frame holds whole among them; each also against the crack's length that
  the recorded frames show (`seen_length_m`: the stretches some frame's
  truth lists as visible, covering a quarter of a pixel or more; a hairline
  tip or branch of 0.1 mm is a tenth of a pixel at 1 mm/px, which no
  camera on the flight could trace).

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


STEP_M = 0.005  # the simulator's spacing of the points it checks along a crack


def crack_points(crack):
    # As the simulator samples a crack: each segment's start and evenly up
    # to its end, the end itself left to the next segment.
    points = []
    for line in crack["lines"]:
        for a, b in zip(line, line[1:]):
            n = max(1, math.ceil(math.dist(a, b) / STEP_M))
            points += [[a[i] + (b[i] - a[i]) * k / n for i in range(3)] for k in range(n)]
    return points


def project(camera, pose, p):
    # World point to pixel through the frame's true pose and plumb_bob lens.
    x, y, z, w = pose["rotation_xyzw"]
    r = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    d = [p[i] - pose["translation"][i] for i in range(3)]
    c = [sum(r[j][i] * d[j] for j in range(3)) for i in range(3)]
    if c[2] <= 0:
        return None
    u, v = c[0] / c[2], c[1] / c[2]
    k1, k2, p1, p2, k3 = camera["distortion"].get("coefficients", [0.0] * 5)
    r2 = u * u + v * v
    radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
    ud = u * radial + 2 * p1 * u * v + p2 * (r2 + 2 * u * u)
    vd = v * radial + p1 * (r2 + 2 * v * v) + 2 * p2 * u * v
    return camera["fx"] * ud + camera["cx"], camera["fy"] * vd + camera["cy"]


def seen_lengths(truth):
    # Per crack, the length of its points some recorded frame shows.
    points = {c["id"]: crack_points(c) for c in truth["cracks"]}
    shown = {cid: set() for cid in points}
    for f in truth["frames"]:
        if f["dropped"]:
            continue
        for v in f["cracks"]:
            visible = v["polyline_px"]
            at = 0
            for j, p in enumerate(points[v["id"]]):
                if at == len(visible):
                    break
                px = project(truth["camera"], f["camera_pose"], p)
                if px and math.dist(px, visible[at]) < 1e-3:
                    shown[v["id"]].add(j)
                    at += 1
    by_id = {c["id"]: c for c in truth["cracks"]}
    return {
        cid: by_id[cid]["length_m"] * len(s) / max(1, len(points[cid]))
        for cid, s in shown.items()
    }


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
    seen_m = seen_lengths(truth)
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
                "seen_length_m": seen_m[cid],
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
            "along_trace_against_seen": summary(
                [abs(r["length_m"] / r["seen_length_m"] - 1) for r in lengths if r["seen_length_m"]]
            ),
            "every_end_seen_against_seen": summary(
                [
                    abs(r["length_m"] / r["seen_length_m"] - 1)
                    for r in rows
                    if r["length_status"] == "measured" and r["seen_length_m"]
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
