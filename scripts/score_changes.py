"""Score `postflight compare` against a simulated repeat's truth.

    score_changes.py EARLIER_FLIGHT EARLIER_RUN LATER_FLIGHT LATER_RUN [...]

Candidates are put on truth cracks as score_measurement.py does (each
run's own truth, so in its own frame); a crack's candidate is the one with
the most frames. For each crack the repeat's truth says grew or widened,
and both runs found, the later candidate's change is looked up in the later
run's `changes.json`:

- grown: recognised when its class is `grown`;
- widened: recognised when its widening exceeds its width uncertainty
  (`widening_mm > width_spread_mm`; a crack that also grew is classed
  `grown`, its widening still recorded);
- new: every candidate classed `new` that lies on a crack older than the
  earlier flight is counted, split by whether the earlier flight's true
  coverage (truth.json `coverage`, the simulator's own) inspected the
  surface under the crack (the target voxel it lies in, or the nearest
  one where that is none; one on surface it never inspected must be
  `first_seen`), and whether it ever had the crack in view.

Each tally is given twice: over every crack both runs found, and over
those both flights also had in a view the View model accepts (see
`usable_views`): a crack seen only blurred, too obliquely or under half a
pixel wide in one flight cannot have had its change measured, and
`not_measured` says so.

Prints one JSON object: the tallies and each judged crack.
"""

import json
import math
import sys
from pathlib import Path

from score_measurement import nearest_crack, samples


def candidates_on_cracks(truth, run):
    """Truth crack id -> the candidate on it with the most frames."""
    cracks = truth["cracks"]
    for c in cracks:
        c["_samples"] = samples(c)
    defects = json.loads((run / "defects.json").read_text())["defects"]
    on = {}
    for d in defects:
        c = nearest_crack(cracks, d["position"])
        if c is not None and (c["id"] not in on or d["frames"] > on[c["id"]]["frames"]):
            on[c["id"]] = d
    return on


def usable_views(truth, view):
    """Truth crack id -> how many of the flight's frames had it in a view
    the View model accepts: a frame not dropped and sharp (blur within
    `max_blur_px`), the crack at least half a pixel wide in it (narrower,
    it darkens a pixel by less than half its own darkness, within the
    noise), its middle within `max_distance_m` and seen at no more than
    `max_incidence_deg`. A crack without one in either flight cannot have
    had its change measured."""
    cracks = {c["id"]: c for c in truth["cracks"]}
    middle = {}
    for cid, c in cracks.items():
        points = samples(c)
        middle[cid] = [sum(p[i] for p in points) / len(points) for i in range(3)]
    counts = {}
    for f in truth["frames"]:
        if f.get("dropped") or f["blur_px"] > view["max_blur_px"]:
            continue
        eye = f["camera_pose"]["translation"]
        for seen in f["cracks"]:
            cid = seen["id"]
            ray = [eye[i] - middle[cid][i] for i in range(3)]
            distance = math.hypot(*ray)
            facing = sum(ray[i] * cracks[cid]["normal"][i] for i in range(3)) / distance
            incidence = math.degrees(math.acos(max(-1.0, min(1.0, facing))))
            if (
                seen["width_px"] >= 0.5
                and distance <= view["max_distance_m"]
                and incidence <= view["max_incidence_deg"]
            ):
                counts[cid] = counts.get(cid, 0) + 1
    return counts


def in_view(truth):
    return {
        c["id"]
        for f in truth["frames"]
        if not f.get("dropped")
        for c in f["cracks"]
    }


def truly_inspected_voxels(truth):
    """Target voxel -> whether the flight's true coverage inspected it."""
    return {tuple(v["voxel"]): v["inspected"] for v in truth["coverage"]["voxels"]}


def truly_inspected(inspected, plan, crack):
    """Whether the true coverage inspected the surface under any point of
    the crack: the target voxel it lies in or, where that is not a target
    (a point on a voxel's edge, a slanted face), the nearest target voxel
    around it, as `postflight compare` reads coverage."""
    res, origin = plan["resolution"], plan["origin"]
    n = crack["normal"]
    for p in samples(crack):
        inside = [p[i] - n[i] * 0.25 * res for i in range(3)]
        v = tuple(math.floor((inside[i] - origin[i]) / res) for i in range(3))
        if v not in inspected:
            around = [
                (sum((origin[i] + (w[i] + 0.5) * res - inside[i]) ** 2 for i in range(3)), w)
                for w in (
                    (v[0] + dx, v[1] + dy, v[2] + dz)
                    for dx in (-1, 0, 1)
                    for dy in (-1, 0, 1)
                    for dz in (-1, 0, 1)
                )
                if w in inspected
            ]
            if not around:
                continue
            v = min(around)[1]
        if inspected[v]:
            return True
    return False


def score_pair(earlier, earlier_run, later, later_run):
    truth_a = json.loads((earlier / "truth.json").read_text())
    truth_b = json.loads((later / "truth.json").read_text())
    changes = json.loads((later_run / "changes.json").read_text())
    by_after = {c["after"]: c for c in changes["changes"] if c["after"]}
    on_a = candidates_on_cracks(truth_a, earlier_run)
    on_b = candidates_on_cracks(truth_b, later_run)
    seen_a = in_view(truth_a)
    usable_a = usable_views(truth_a, json.loads((earlier / "plan.json").read_text())["view"])
    usable_b = usable_views(truth_b, json.loads((later / "plan.json").read_text())["view"])
    crack_of = {}
    for cid, d in on_b.items():
        crack_of[d["id"]] = cid
    rows = []
    for change in truth_b["repeat"]["changes"]:
        cid = change["id"]
        if cid not in on_a or cid not in on_b:
            continue
        record = by_after.get(on_b[cid]["id"], {})
        widening, spread = record.get("widening_mm"), record.get("width_spread_mm")
        rows.append(
            {
                "pair": later.name,
                "crack": cid,
                "truth": change["change"],
                "truth_widened": change.get("widened", False),
                "class": record.get("change"),
                "length_before_m": record.get("length_before_m"),
                "length_after_m": record.get("length_after_m"),
                "true_length_before_m": change["length_before_m"],
                "true_length_m": change["length_m"],
                "width_before_mm": record.get("width_before_mm"),
                "width_after_mm": record.get("width_after_mm"),
                "true_width_before_mm": change.get("width_before_mm"),
                "true_width_mm": change.get("width_mm"),
                "widened": widening is not None
                and spread is not None
                and widening > spread,
                "usable_in_both": cid in usable_a and cid in usable_b,
            }
        )
    old = {c["id"] for c in truth_b["repeat"]["changes"] if c["change"] != "new"}
    plan_a = json.loads((earlier / "plan.json").read_text())
    cracks_a = {c["id"]: c for c in truth_a["cracks"]}
    inspected_a = truly_inspected_voxels(truth_a)
    called_new = []
    for c in changes["changes"]:
        if c["change"] != "new" or c["after"] not in crack_of:
            continue
        cid = crack_of[c["after"]]
        if cid in old:
            called_new.append(
                {
                    "crack": cid,
                    "earlier_had_in_view": cid in seen_a,
                    "earlier_inspected": truly_inspected(inspected_a, plan_a, cracks_a[cid]),
                }
            )
    return rows, called_new, changes["counts"], changes["registration"]


def grown(r):
    return r["truth"] == "grown"


def widened(r):
    return r["truth_widened"]


def unchanged(r):
    return r["truth"] == "unchanged" and not r["truth_widened"]


def tally(rows, judged, right):
    judged = [r for r in rows if judged(r)]
    return {"right": sum(1 for r in judged if right(r)), "of": len(judged)}


def main(args):
    rows, called_new, pairs = [], [], []
    for i in range(0, len(args), 4):
        a, ar, b, br = (Path(p) for p in args[i : i + 4])
        r, n, counts, registration = score_pair(a, ar, b, br)
        rows += r
        called_new += n
        pairs.append({"pair": b.name, "counts": counts, "registration": registration})
    usable = [r for r in rows if r["usable_in_both"]]
    out = {
        "grown": tally(rows, grown, lambda r: r["class"] == "grown"),
        "widened": tally(rows, widened, lambda r: r["widened"]),
        "unchanged": tally(rows, unchanged, lambda r: r["class"] == "unchanged"),
        "with_a_usable_view_in_both_flights": {
            "grown": tally(usable, grown, lambda r: r["class"] == "grown"),
            "widened": tally(usable, widened, lambda r: r["widened"]),
            "unchanged": tally(usable, unchanged, lambda r: r["class"] == "unchanged"),
        },
        "old_cracks_called_new": {
            "on_surface_the_earlier_flight_inspected": sum(
                1 for n in called_new if n["earlier_inspected"]
            ),
            "on_surface_it_never_inspected": sum(
                1 for n in called_new if not n["earlier_inspected"]
            ),
            "earlier_never_had_in_view": sum(
                1 for n in called_new if not n["earlier_had_in_view"]
            ),
        },
        "pairs": pairs,
        "cracks": rows,
    }
    json.dump(out, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    if len(sys.argv) < 5 or (len(sys.argv) - 1) % 4:
        sys.exit(
            "usage: score_changes.py EARLIER_FLIGHT EARLIER_RUN LATER_FLIGHT LATER_RUN [...]"
        )
    main(sys.argv[1:])
