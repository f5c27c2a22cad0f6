#!/usr/bin/env python3
"""Crack widths read with a crack-width gauge on real structures, as a
flight, and postflight's widths scored against the gauge: the evaluation
that docs/evaluation.md's "Against a crack-width gauge" figures come from.

    gauge_cracks.py write --site DIR --out DIR [--limit N] [--only thin|resolved]
    gauge_cracks.py score FLIGHT RUN [FLIGHT RUN ...]
    gauge_cracks.py profiles --site DIR [--site DIR ...]

The readings (Benz & Rodehorst, MVA 2021; GPL-3.0, evaluation only, in
../shared/data/gauge) each give the width a gauge read (mm), the photo's
resolution at the crack (mm per pixel) and the grey levels the camera
recorded across the crack there: 32 samples, a pixel apart. The photos
themselves are not published.

`write` lays each reading's profile into a photo of its own: a crack with
exactly that cross-section (the profile's darkness below its surface,
out to where it comes back to the surface on each side) along a gentle
meander across a 512 x 256 frame, on a surface of the profile's
brightness with fresh noise of the profile's own (its outer samples'
robust sigma), as a grey PNG. Each photo is a frame of one flight over
a flat surface (scripts/real_cracks.py's `fly`): a camera looking straight
down through a 4000 px lens from the height that gives the reading's own
resolution. A reading whose resolution is not a camera's (one of
BridgeS's says 26.7 mm per pixel, so 0.007 px for a crack its profile
shows 2 px wide) is left out and said so.

`score` puts each reading's candidates (those whose best view is its
frame and whose trace lies on its crack, within 3 px) against the gauge:
the width the condition state follows (`max_width_mm`) and the median,
error in pixels and relative, by gauge width (up to 2 px, 2-6, over 6),
the share within 0.05, 0.1 and 0.2 mm, and the condition states under the
default limits (0.30 and 1.27 mm). A reading no candidate measured is
counted as missed, never as right.

`profiles` scores estimators on the profiles alone (no photo, no
detector): what a width estimator can do at best on these readings.
"""

import argparse
import io
import json
import math
import sys
from pathlib import Path

import numpy as np
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))
from real_cracks import STATE_LIMITS_MM, Shot, fly, image_points, state  # noqa: E402

SIZE = (512, 256)
FOCAL_PX = 4000.0
# A resolution no camera flying an inspection has (mm per pixel).
MAX_RES_MM = 2.0
MEANDER_PX = 6.0
MEANDER_PERIOD_PX = 420.0
ON_LINE_PX = 3.0
BANDS = (("up to 2 px", 0.0, 2.0), ("2-6 px", 2.0, 6.0), ("over 6 px", 6.0, math.inf))
# A site's thin cracks, flown alone: no wider than the blur spreads a line.
THIN_PX = 2.0


class Reading:
    """One gauge reading: its CSV's numbers and the profile across the crack."""

    def __init__(self, path):
        lines = path.read_text().splitlines()
        names = [h.strip() for h in lines[0].split(",")]
        values = dict(zip(names, (float(v) for v in lines[1].split(","))))
        if lines[2].strip() != "intensities":
            raise ValueError(f"{path}: no intensities line")
        self.name = path.stem
        self.width_mm = values["width_m"]  # millimetres, despite the name (README)
        self.res_mm = values["mean_res"]
        self.width_px = self.width_mm / self.res_mm
        self.profile = np.array([float(v) for v in lines[3].split(",") if v.strip()])

    def surface(self):
        """The surface's brightness and noise: the median and robust sigma
        of the outer quarters, a linear trend taken out."""
        n = len(self.profile)
        x = np.r_[0:n // 4, n - n // 4:n]
        y = self.profile[x]
        slope, level = np.polyfit(x, y, 1)
        residual = y - (slope * x + level)
        return float(np.median(y)), float(max(1.4826 * np.median(np.abs(residual - np.median(residual))), 0.5))

    def darkness(self):
        """The crack's darkness at offsets (pixels) from its centre: below the
        surface's level on each side (the median of that side's outer
        quarter, a line between the two across the crack, so a step in the
        surface's brightness is not taken for crack), from the profile's
        darkest sample in its middle half out to where it first comes back
        to that level on each side; zero beyond."""
        p = self.profile
        n = len(p)
        left, right = np.median(p[: n // 4]), np.median(p[n - n // 4:])
        c = n // 4 + int(np.argmin(p[n // 4: n - n // 4]))
        lo = c
        while lo > 0 and p[lo - 1] < left:
            lo -= 1
        hi = c
        while hi < n - 1 and p[hi + 1] < right:
            hi += 1
        level = np.interp(np.arange(n), [lo, hi], [left, right])
        d = np.zeros(n)
        d[lo:hi + 1] = np.clip(level[lo:hi + 1] - p[lo:hi + 1], 0.0, None)
        # Centre the crack on its darkness's centroid, not its darkest sample.
        centre = float(np.sum(np.arange(n) * d) / max(np.sum(d), 1e-9))
        return np.arange(n) - centre, d


def readings(site):
    paths = sorted(Path(site).glob("*.csv"))
    if not paths:
        sys.exit(f"gauge_cracks: no readings (*.csv) in {site}")
    return [Reading(p) for p in paths]


def meander(x):
    """The crack's centre line: y at column x, and its slope."""
    k = 2 * math.pi / MEANDER_PERIOD_PX
    return SIZE[1] / 2 + MEANDER_PX * np.sin(k * x), MEANDER_PX * k * np.cos(k * x)


def photo(reading, seed):
    """The reading's profile laid along the meander, on a surface of its
    brightness and noise: a grey image."""
    w, h = SIZE
    s, sigma = reading.surface()
    t, d = reading.darkness()
    ys, xs = np.mgrid[0:h, 0:w].astype(float) + 0.5
    yc, slope = meander(xs)
    across = (ys - yc) / np.sqrt(1 + slope**2)
    dark = np.interp(across, t, d, left=0.0, right=0.0)
    noise = np.random.default_rng(seed).normal(0.0, sigma, size=(h, w))
    return np.clip(np.round(s - dark + noise), 0, 255).astype(np.uint8)


def kept(reading, only):
    """Whether a reading belongs to the subset `only` flies: its thin cracks
    (up to 2 px, thinner than the blur) or its resolved ones (wider)."""
    thin = reading.width_px <= THIN_PX
    return only == "all" or (only == "thin") == thin


def write(args):
    out = Path(args.out)
    shots, left_out = [], []
    # A reading's photo is the same in every subset: its noise is seeded by
    # its place among the site's readings.
    for i, r in enumerate(readings(args.site)[: args.limit or None]):
        if not kept(r, args.only):
            continue
        if not 0 < r.res_mm <= MAX_RES_MM:
            left_out.append(f"{r.name} ({r.res_mm:.3g} mm per pixel)")
            continue
        buffer = io.BytesIO()
        Image.fromarray(photo(r, i)).save(buffer, format="PNG")
        shots.append(Shot(buffer.getvalue(), "png", SIZE, FOCAL_PX * r.res_mm / 1000.0, {
            "reading": r.name, "width_mm": r.width_mm, "res_mm": r.res_mm, "width_px": r.width_px,
            "downsample": 1, "gsd_mm": r.res_mm}))
    fly(out, FOCAL_PX, shots)
    (out / "readings.json").write_text(json.dumps({"site": str(args.site), "left_out": left_out,
                                                   "frames": [s.meta for s in shots]}, indent=1))
    print(f"gauge_cracks: {len(shots)} readings of {args.site} in {out}"
          + (f"; left out: {', '.join(left_out)}" if left_out else ""), file=sys.stderr)


def measured(flight, run):
    """Each reading with the widths postflight gave its crack (or none)."""
    frames = json.loads((Path(flight) / "readings.json").read_text())["frames"]
    defects = json.loads((Path(run) / "defects.json").read_text())["defects"]
    by_time = {f["time_ns"]: dict(f, candidates=[]) for f in frames}
    for d in defects:
        frame = by_time.get(d["best"]["time_ns"])
        if frame is None:
            continue
        pts = image_points(d, frame)
        yc, _ = meander(pts[:, 0])
        if np.mean(np.abs(pts[:, 1] - yc) <= ON_LINE_PX) >= 0.5:
            frame["candidates"].append(d)
    rows = []
    for f in by_time.values():
        widths = [c for c in f["candidates"] if (c.get("width") or {}).get("max_mm") is not None]
        # The crack as an inspector would read it: the longest measured candidate.
        best = max(widths, key=lambda c: c["length_m"] or 0.0, default=None)
        width = best["width"] if best else {}
        rows.append({"reading": f["reading"], "gauge_mm": f["width_mm"], "res_mm": f["res_mm"],
                     "gauge_px": f["width_px"], "found": bool(f["candidates"]),
                     "max_mm": width.get("max_mm"), "median_mm": width.get("median_mm"),
                     "narrower_than_mm": next((c["width"]["narrower_than_mm"] for c in f["candidates"]
                                               if c.get("width") and c["width"].get("narrower_than_mm")), None),
                     "state": best.get("condition") if best else None})
    return rows


def summary(title, gauge_px, est_px, res_mm, states=None):
    """The figures of one set of widths (NaN where not measured) against the gauge."""
    gauge_px, est_px, res_mm = map(np.asarray, (gauge_px, est_px, res_mm))
    ok = np.isfinite(est_px)
    err = est_px - gauge_px
    print(f"\n### {title}: {len(gauge_px)} readings, {ok.sum()} measured")
    print("| gauge width | readings | measured | mean abs error | median error | median signed |")
    print("|---|---|---|---|---|---|")
    for band, low, high in BANDS + (("all", 0.0, math.inf),):
        m = (gauge_px > low) & (gauge_px <= high)
        k = m & ok
        if not m.any():
            continue
        if k.any():
            rel = err[k] / gauge_px[k]
            print(f"| {band} | {m.sum()} | {k.sum()} | {np.mean(np.abs(err[k])):.2f} px | "
                  f"{np.median(np.abs(rel)):.0%} | {np.median(rel):+.0%} |")
        else:
            print(f"| {band} | {m.sum()} | 0 | - | - | - |")
    mm = np.where(ok, np.abs(err) * res_mm, np.inf)
    print("within 0.05, 0.1, 0.2 mm (of all readings): "
          + ", ".join(f"{np.mean(mm <= tol):.0%}" for tol in (0.05, 0.1, 0.2)))
    if states is not None:
        truth = [state(g * r) for g, r in zip(gauge_px, res_mm)]
        right = sum(a == b for a, b in zip(truth, states))
        print(f"condition states right for {right} of {len(truth)} ({right / len(truth):.0%}); "
              f"{sum(s is None for s in states)} without one")
        confusion = {}
        for a, b in zip(truth, states):
            confusion[(a, b)] = confusion.get((a, b), 0) + 1
        print("states (gauge -> measured): "
              + ", ".join(f"{a}->{b}: {n}" for (a, b), n in sorted(confusion.items(), key=str)))


def score(args):
    if len(args.runs) % 2:
        sys.exit("gauge_cracks score: give FLIGHT RUN pairs")
    everything = []
    for flight, run in zip(args.runs[::2], args.runs[1::2]):
        rows = measured(flight, run)
        left_out = json.loads((Path(flight) / "readings.json").read_text())["left_out"]
        print(f"\n## {run}: {len(rows)} readings, {sum(r['found'] for r in rows)} found by the detector"
              + (f"; left out: {', '.join(left_out)}" if left_out else ""))
        report(rows)
        everything += rows
    if len(args.runs) > 2:
        print("\n## every site")
        report(everything)


def report(rows):
    g = [r["gauge_px"] for r in rows]
    res = [r["res_mm"] for r in rows]
    for key, title in (("max_mm", "widest (the state's width)"), ("median_mm", "median")):
        est = [r[key] / r["res_mm"] if r[key] is not None else math.nan for r in rows]
        summary(title, g, est, res, [r["state"] for r in rows] if key == "max_mm" else None)


def profiles(args):
    """Estimators on the profiles alone."""
    rows = [r for site in args.site for r in readings(site) if 0 < r.res_mm <= MAX_RES_MM]
    g = [r.width_px for r in rows]
    res = [r.res_mm for r in rows]

    def integral(r):
        s, _ = r.surface()
        _, d = r.darkness()
        return float(d.sum()), s

    def states(px):
        return [state(p * r.res_mm) for p, r in zip(px, rows)]

    for title, fn in (
        ("darkness integral over (surface - 20 grey levels), the rectangle transform's base",
         lambda r: integral(r)[0] / (integral(r)[1] - 20.0)),
        ("darkness integral over 85% of the surface", lambda r: integral(r)[0] / (0.85 * integral(r)[1])),
        ("darkness integral over the profile's own depth", lambda r: integral(r)[0] / r.darkness()[1].max()),
    ):
        px = [fn(r) for r in rows]
        summary(title, g, px, res, states(px))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    w = sub.add_parser("write")
    w.add_argument("--site", required=True)
    w.add_argument("--out", required=True)
    w.add_argument("--limit", type=int, default=0)
    w.add_argument("--only", choices=("all", "thin", "resolved"), default="all",
                   help="fly the site's thin cracks (up to 2 px) or its resolved ones alone")
    s = sub.add_parser("score")
    s.add_argument("runs", nargs="+")
    p = sub.add_parser("profiles")
    p.add_argument("--site", action="append", required=True)
    args = ap.parse_args()
    {"write": write, "score": score, "profiles": profiles}[args.command](args)


if __name__ == "__main__":
    main()
