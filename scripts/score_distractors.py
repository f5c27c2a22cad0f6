"""Score a run's candidates on a flight simulated with --distractors.

    score_distractors.py FLIGHT_DIR RUN_DIR [FLIGHT_DIR RUN_DIR ...]

Each candidate, and each group of views localise set aside as a joint
(`localise.json` `set_aside`), is put on what truth has there: a crack
(within 0.3 m of its centre line, as score_measurement.py matches), else
the nearest distractor within 0.3 m of its line (a stain: of its centre,
within its radius and 0.3 m), else nothing. Precision is the share of
candidates on cracks; "before" counts what was set aside as proposed too,
which is what a detector without the joint rule proposes.

Prints one JSON object.
"""

import json
import math
import sys
from pathlib import Path

from score_measurement import MATCH_M, nearest_crack, samples


def on_segment(p, a, b):
    ab = [b[i] - a[i] for i in range(3)]
    n = sum(v * v for v in ab)
    s = 0.0 if n == 0 else max(0.0, min(1.0, sum((p[i] - a[i]) * ab[i] for i in range(3)) / n))
    return math.dist(p, [a[i] + ab[i] * s for i in range(3)])


def what_is_there(truth, p):
    if nearest_crack(truth["cracks"], p) is not None:
        return "crack"
    best = None
    for m in truth.get("distractors", []):
        a, b = m["line"]
        reach = MATCH_M + (m["width_mm"] / 2000.0 if m["kind"] == "stain" else 0.0)
        d = on_segment(p, a, b)
        if d <= reach and (best is None or d < best[0]):
            best = (d, m["kind"])
    return best[1] if best else "nothing"


def score(flight, run):
    truth = json.loads((flight / "truth.json").read_text())
    for c in truth["cracks"]:
        c["_samples"] = samples(c)
    defects = json.loads((run / "defects.json").read_text())["defects"]
    set_aside = json.loads((run / "localise.json").read_text()).get("set_aside", [])
    proposed = [what_is_there(truth, d["position"]) for d in defects]
    aside = [what_is_there(truth, s["position"]) for s in set_aside]
    return proposed, aside


def counts(kinds):
    out = {}
    for k in kinds:
        out[k] = out.get(k, 0) + 1
    return dict(sorted(out.items()))


def precision(kinds):
    return sum(1 for k in kinds if k == "crack") / len(kinds) if kinds else None


def main(args):
    proposed, aside, flights = [], [], []
    for flight, run in zip(args[::2], args[1::2]):
        p, a = score(Path(flight), Path(run))
        proposed += p
        aside += a
        flights.append({"flight": Path(flight).name, "proposed": counts(p), "set_aside": counts(a)})
    before = proposed + aside
    out = {
        "before": {
            "candidates": len(before),
            "precision": precision(before),
            "joints_share": before.count("joint") / len(before) if before else None,
        },
        "after": {
            "candidates": len(proposed),
            "precision": precision(proposed),
            "joints_share": proposed.count("joint") / len(proposed) if proposed else None,
        },
        "proposed": counts(proposed),
        "set_aside": counts(aside),
        "flights": flights,
    }
    json.dump(out, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    if len(sys.argv) < 3 or len(sys.argv) % 2 == 0:
        sys.exit("usage: score_distractors.py FLIGHT_DIR RUN_DIR [FLIGHT_DIR RUN_DIR ...]")
    main(sys.argv[1:])
