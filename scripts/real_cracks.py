#!/usr/bin/env python3
"""Real crack photographs as a flight, and postflight's candidates scored
against the photos' own masks (drawn by people): the evaluation that
docs/evaluation.md's "Real cracks" figures come from.

    real_cracks.py write --photos DIR --gsd MM --out DIR [--limit N] [--downsample K]
    real_cracks.py score FLIGHT RUN [FLIGHT RUN ...] [--pair FLIGHT RUN FLIGHT RUN]
    real_cracks.py darkness --photos DIR [--limit N]
    real_cracks.py profiles FLIGHT RUN [--most N]

`write` lays each photo (with its mask `lab/NAME_mask.png` beside `img/`)
on a flat surface: a camera 1.2 m above it looking straight down, one
photo per 1 m cell (no two frames share ground), its focal length set so
a pixel spans `--gsd` millimetres. `--downsample K` averages K x K pixel
blocks first (the same cracks seen by a coarser camera: `--gsd` is then
the coarse pixel's). It writes `flight.mcap` (ROS 2: the photos as
CompressedImage, CameraInfo, PoseStamped, /tf_static, the surface as a
PointCloud2 map) with the official `mcap-ros2-support` writer, and
`photos.json` (each frame's photo, time and camera).

`score` reads each run's `defects.json` and scores it against the masks:
- a candidate is on a crack when most of its trace, projected back into
  its photo, lies within 3 px of the mask;
- a crack is a connected component of the mask (8-neighbours) of 30
  pixels or more; it is found when an on-crack candidate's trace comes
  within 3 px of it;
- a crack's true width on its mask's medial axis is twice the distance
  to the mask's edge (scikit-image's skeleton and SciPy's Euclidean
  distance transform of the mask drawn 4 times finer, so the axis of an
  even width runs down its middle); a candidate's true width is the 95th
  percentile of those on the axis within 3 px of its trace (as
  postflight's `max_mm` is the 95th percentile along its line), and its
  true condition state that width's under the default material's limits
  (0.30 and 1.27 mm);
- the review order is the queue's (confidence times length).
`--pair` compares two runs of the same photos at two GSDs: candidates
matched by photo and trace, and whether their widths agree within the
sum of their uncertainties.

`darkness` says how dark the photos' cracks are for their drawn width
(see its function); `profiles`, of the wide cracks a run measured, how
wide the photo's own grey levels are at a half, a quarter and a tenth
of their depth, against the mask and postflight (see its function).
"""

import argparse
import functools
import io
import json
import math
import sys
from pathlib import Path

import numpy as np
from PIL import Image

HEIGHT_M = 1.2
CELL_M = 1.0
COLUMNS = 10
FRAME_S = 0.5
T0_NS = 1_700_000_000 * 10**9
NEAR_PX = 3.0
MIN_COMPONENT_PX = 30
SUB = 4
STATE_LIMITS_MM = (0.30, 1.27)
STATES = ("good", "fair", "poor")
# Where a mask is no longer mostly blur: the widths scored against it alone.
WIDE_PX = 6.0
# The mask's widest stretch, as postflight reads a crack's (localise's
# view_width: four steps either side, none within eight of a fork).
STRETCH_PX = 4.0
FORK_PX = 8.0


def mask_path(photo):
    return photo.parent.parent / "lab" / (photo.stem + "_mask.png")


def photos_in(folder, limit):
    photos = sorted(p for p in Path(folder).iterdir() if p.suffix.lower() in (".jpg", ".jpeg", ".png"))
    return photos[:limit] if limit else photos


def cell(i):
    return (CELL_M * (i % COLUMNS), CELL_M * (i // COLUMNS))


# --- write ---------------------------------------------------------------


def write(args):
    out = Path(args.out)
    photos = photos_in(args.photos, args.limit)
    if not photos:
        sys.exit(f"real_cracks: no photos in {args.photos}")
    f = HEIGHT_M * 1000.0 / args.gsd
    shots = []
    for photo in photos:
        img = Image.open(photo).convert("RGB")
        if args.downsample > 1:
            k = args.downsample
            w, h = img.width // k, img.height // k
            a = np.asarray(img, dtype=np.float64)[: h * k, : w * k]
            img = Image.fromarray(np.round(a.reshape(h, k, w, k, 3).mean(axis=(1, 3))).astype(np.uint8))
            buffer = io.BytesIO()
            img.save(buffer, format="PNG")
            data, fmt = buffer.getvalue(), "png"
        else:
            data, fmt = photo.read_bytes(), "rgb8; jpeg compressed bgr8"
        shots.append(Shot(data, fmt, img.size, HEIGHT_M, {
            "photo": str(photo.resolve()), "downsample": args.downsample, "gsd_mm": args.gsd}))
    fly(out, f, shots)
    (out / "photos.json").write_text(json.dumps({"gsd_mm": args.gsd, "frames": [
        s.meta for s in shots]}, indent=1))
    print(f"real_cracks: {len(photos)} photos at {args.gsd} mm per pixel (f = {f:.0f} px) in {out}",
          file=sys.stderr)


class Shot:
    """One photo of a flight over a flat surface: its encoded bytes and
    their format (a CompressedImage's), its size, the camera's height above
    the surface, and what the scorer is to know of it (`meta`, to which
    `fly` adds the frame's time, camera and lens)."""

    def __init__(self, data, fmt, size, height_m, meta):
        self.data, self.fmt, self.size, self.height_m, self.meta = data, fmt, size, height_m, meta


def fly(out, f, shots):
    """Write `out/flight.mcap`: each shot taken looking straight down from
    its height over its own 1 m cell (no two frames share ground), through
    one lens of focal length `f` pixels (so a pixel spans height / f on the
    surface); ROS 2 messages (the photos as CompressedImage, CameraInfo,
    PoseStamped, /tf_static, the surface as a PointCloud2 map) with the
    official `mcap-ros2-support` writer."""
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "fixtures"))
    from mcap.writer import CompressionType
    from write_flight import stamp, write_messages  # the tests' ROS 2 writer

    out.mkdir(parents=True, exist_ok=True)
    messages = []

    def add(topic, typ, msg, ns):
        messages.append((ns, topic, typ, msg))

    identity = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    add("/tf_static", "tf2_msgs/TFMessage", {"transforms": [{
        "header": {"stamp": stamp(T0_NS), "frame_id": "base_link"}, "child_frame_id": "camera_optical",
        "transform": {"translation": {"x": 0.0, "y": 0.0, "z": 0.0}, "rotation": identity}}]}, T0_NS)
    # Looking straight down: the optical frame's x east, y south, z down.
    down = {"x": 1.0, "y": 0.0, "z": 0.0, "w": 0.0}
    end_s = FRAME_S * (len(shots) + 1)
    for k in range(int(end_s / 0.05) + 1):
        t = 0.05 * k
        # Hovering over cell i from (i + 0.5 - 0.2) s to (i + 0.5 + 0.2) s, flying between.
        s = t / FRAME_S - 0.5
        i = min(max(math.floor(s), 0), len(shots) - 1)
        j = min(i + 1, len(shots) - 1)
        frac = min(max((s - i - 0.4) / 0.2, 0.0), 1.0) if s > i else 0.0
        (x0, y0), (x1, y1) = cell(i), cell(j)
        z0, z1 = shots[i].height_m, shots[j].height_m
        pos = {"x": x0 + frac * (x1 - x0), "y": y0 + frac * (y1 - y0), "z": z0 + frac * (z1 - z0)}
        ns = T0_NS + round(t * 1e9)
        add("/slam/pose", "geometry_msgs/PoseStamped", {
            "header": {"stamp": stamp(ns), "frame_id": "map"},
            "pose": {"position": pos, "orientation": down}}, ns)
    for i, shot in enumerate(shots):
        w, h = shot.size
        t = FRAME_S * (i + 0.5)
        ns = T0_NS + round(t * 1e9)
        header = {"stamp": stamp(ns), "frame_id": "camera_optical"}
        cx, cy = w / 2.0, h / 2.0
        add("/camera/image/compressed", "sensor_msgs/CompressedImage",
            {"header": header, "format": shot.fmt, "data": shot.data}, ns + 1000)
        add("/camera/camera_info", "sensor_msgs/CameraInfo", {
            "header": header, "height": h, "width": w, "distortion_model": "plumb_bob",
            "d": [0.0] * 5, "k": [f, 0, cx, 0, f, cy, 0, 0, 1], "r": [1, 0, 0, 0, 1, 0, 0, 0, 1],
            "p": [f, 0, cx, 0, 0, f, cy, 0, 0, 0, 1, 0], "binning_x": 0, "binning_y": 0,
            "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False}}, ns + 1000)
        x, y = cell(i)
        shot.meta.update({"time_ns": ns, "camera": [x, y, shot.height_m], "focal_px": f,
                          "centre_px": [cx, cy], "width": w, "height": h})
    # The surface: a 1.2 m square of points 2 cm apart under each camera.
    grid = np.arange(-0.6, 0.6001, 0.02)
    gx, gy = np.meshgrid(grid, grid)
    points = np.concatenate([
        np.stack([gx.ravel() + cell(i)[0], gy.ravel() + cell(i)[1], np.zeros(gx.size)], axis=1)
        for i in range(len(shots))]).astype("<f4")
    add("/map", "sensor_msgs/PointCloud2", {
        "header": {"stamp": stamp(T0_NS), "frame_id": "map"}, "height": 1, "width": len(points),
        "fields": [{"name": n, "offset": 4 * k, "datatype": 7, "count": 1} for k, n in enumerate("xyz")],
        "is_bigendian": False, "point_step": 12, "row_step": 12 * len(points),
        "data": points.tobytes(), "is_dense": True}, T0_NS + round(end_s * 1e9))
    messages.sort(key=lambda m: m[0])
    write_messages(out / "flight.mcap", messages, compression=CompressionType.ZSTD)


# --- score ---------------------------------------------------------------


class Truth:
    """One photo's mask: crack pixels, components, skeleton widths."""

    def __init__(self, photo):
        from scipy import ndimage
        from skimage.morphology import skeletonize

        self.on = np.asarray(Image.open(mask_path(Path(photo))).convert("L")) >= 128
        labels, n = ndimage.label(self.on, structure=np.ones((3, 3)))
        sizes = ndimage.sum(self.on, labels, range(1, n + 1))
        self.components = [k + 1 for k in range(n) if sizes[k] >= MIN_COMPONENT_PX]
        self.labels = labels
        # Distance to the nearest pixel off the mask, and so from the edge.
        self.to_crack = ndimage.distance_transform_edt(~self.on)
        # Widths on the mask's medial axis: skeleton and distances of the
        # mask drawn SUB times finer, so the axis of a crack an even number
        # of pixels wide runs down its middle (on pixel centres it runs a
        # half pixel off, and scores a 4 px crack 3 px wide). A fine
        # pixel's distance to the nearest fine pixel off the mask is half a
        # fine pixel more than to the near edge, and the fine axis of a
        # crack (an even number of fine pixels wide) runs half a fine pixel
        # nearer that edge than the far one: twice that distance is the
        # width (a crack w px wide, 4w fine pixels, scores w).
        fine = np.kron(self.on, np.ones((SUB, SUB), dtype=bool))
        inside = ndimage.distance_transform_edt(fine)
        ys, xs = np.nonzero(skeletonize(fine))
        self.skeleton = np.stack([(xs + 0.5) / SUB - 0.5, (ys + 0.5) / SUB - 0.5], axis=1)
        self.widths = 2.0 * inside[ys, xs] / SUB

    def pixels(self, pts):
        """Each point's pixel (row and column indices), clipped to the mask."""
        h, w = self.on.shape
        return (np.clip(np.floor(pts[:, 1]).astype(int), 0, h - 1),
                np.clip(np.floor(pts[:, 0]).astype(int), 0, w - 1))

    def near(self, pts):
        """Each point's distance to the mask, pixels."""
        return self.to_crack[self.pixels(pts)]

    def touched(self, pts):
        """Components some point comes within NEAR_PX of."""
        from scipy import ndimage

        hit = np.zeros_like(self.on)
        hit[self.pixels(pts)] = True
        hit = ndimage.binary_dilation(hit, iterations=int(NEAR_PX))
        return set(np.unique(self.labels[hit & self.on])) & set(self.components)

    def width_px(self, pts, q=95):
        """The `q`th percentile of the true widths on the axis near `pts`."""
        if len(self.skeleton) == 0:
            return None
        from scipy.spatial import cKDTree

        d, _ = cKDTree(pts).query(self.skeleton)
        near = self.widths[d <= NEAR_PX]
        return float(np.percentile(near, q)) if len(near) else None

    def widest_stretch_px(self, pts):
        """The mask's widest stretch near `pts`, read the way postflight
        reads a crack's: the median width on the medial axis within
        STRETCH_PX of a point, the widest such, none within FORK_PX of a
        junction of the axis (where a disc spans two branches)."""
        from scipy import ndimage
        from scipy.spatial import cKDTree
        from skimage.morphology import skeletonize

        if len(self.skeleton) == 0:
            return None
        if not hasattr(self, "_axis"):
            fine = skeletonize(np.kron(self.on, np.ones((SUB, SUB), dtype=bool)))
            branches = ndimage.convolve(fine.astype(int), np.ones((3, 3), dtype=int), mode="constant") - 1
            ys, xs = np.nonzero(fine & (branches >= 3))
            junctions = np.stack([(xs + 0.5) / SUB - 0.5, (ys + 0.5) / SUB - 0.5], axis=1)
            self._axis = (cKDTree(self.skeleton), cKDTree(junctions) if len(junctions) else None)
        axis, junctions = self._axis
        d, _ = cKDTree(pts).query(self.skeleton)
        near = np.nonzero(d <= NEAR_PX)[0]
        if junctions is not None and len(near):
            near = near[junctions.query(self.skeleton[near])[0] > FORK_PX]
        stretches = [np.median(self.widths[axis.query_ball_point(self.skeleton[i], STRETCH_PX)]) for i in near[::SUB]]
        return float(max(stretches)) if stretches else None


@functools.lru_cache(maxsize=None)
def truth_of(photo):
    return Truth(photo)


def state(width_mm):
    if width_mm is None:
        return None
    return STATES[sum(width_mm > limit for limit in STATE_LIMITS_MM)]


def densify(line, step):
    out = []
    for a, b in zip(line[:-1], line[1:]):
        n = max(1, int(math.ceil(np.linalg.norm(np.subtract(b, a)) / step)))
        out.extend(np.add(a, np.outer(np.arange(n) / n, np.subtract(b, a))))
    out.append(line[-1])
    return np.array(out)


def image_points(candidate, frame):
    """The candidate's trace in its photo's pixels (of the mask, at full size)."""
    f, (cx, cy), (x0, y0, z0) = frame["focal_px"], frame["centre_px"], frame["camera"]
    k = frame["downsample"]
    lines = candidate["trace"] or [[candidate["position"]]]
    pts = np.concatenate([densify(np.asarray(line), frame["gsd_mm"] / 2000.0) for line in lines])
    u = cx + f * (pts[:, 0] - x0) / (z0 - pts[:, 2])
    v = cy - f * (pts[:, 1] - y0) / (z0 - pts[:, 2])
    return np.stack([u, v], axis=1) * k


def scored_run(flight, run):
    photos = json.loads((Path(flight) / "photos.json").read_text())
    by_time = {f["time_ns"]: f for f in photos["frames"]}
    defects = json.loads((Path(run) / "defects.json").read_text())
    defects = defects["defects"] if isinstance(defects, dict) else defects
    truths = {}
    rows = []
    for d in defects:
        frame = by_time.get(d["best"]["time_ns"])
        if frame is None:
            continue
        truth = truths.setdefault(frame["photo"], truth_of(frame["photo"]))
        pts = image_points(d, frame)
        on = float(np.mean(truth.near(pts) <= NEAR_PX)) >= 0.5
        true_px = truth.width_px(pts) if on else None
        median_px = truth.width_px(pts, 50) if on else None
        stretch_px = truth.widest_stretch_px(pts) if on and true_px and true_px >= WIDE_PX else None
        mm_per_full_px = frame["gsd_mm"] / frame["downsample"]
        width = d.get("width") or {}
        size = d["length_m"] or 0.0
        rows.append({
            "id": d["id"], "photo": Path(frame["photo"]).name, "on": on,
            "components": truth.touched(pts) if on else set(),
            "true_px": true_px, "true_mm": None if true_px is None else true_px * mm_per_full_px,
            "true_median_mm": None if median_px is None else median_px * mm_per_full_px,
            "true_stretch_mm": None if stretch_px is None else stretch_px * mm_per_full_px,
            "median_mm": width.get("median_mm"),
            "max_mm": width.get("max_mm"), "uncertainty_mm": width.get("uncertainty_mm"),
            "narrower_than_mm": width.get("narrower_than_mm"),
            "method": width.get("method"), "fit": width.get("fit"),
            "state": d.get("condition"), "priority": d["confidence"] * max(size, 0.05),
            "confidence": d["confidence"], "pts": pts,
        })
    for photo in {f["photo"] for f in photos["frames"]}:
        truths.setdefault(photo, truth_of(photo))
    return photos, truths, rows


def report(flight, run):
    photos, truths, rows = scored_run(flight, run)
    on = [r for r in rows if r["on"]]
    components = sum(len(t.components) for t in truths.values())
    found = set()
    for r in on:
        found |= {(r["photo"], c) for c in r["components"]}
    print(f"\n## {run}: {len(photos['frames'])} photos at {photos['gsd_mm']} mm per pixel")
    print(f"candidates {len(rows)}, on cracks {len(on)} (precision {len(on) / max(len(rows), 1):.2f}); "
          f"cracks (mask components) {components}, found {len(found)} (recall {len(found) / max(components, 1):.2f})")
    print("| true width | candidates | measured | median error | median signed error | 90th percentile |")
    print("|---|---|---|---|---|---|")
    bands = {"1-3 px": (1, 3), "3-6 px": (3, 6), "6 px and over": (6, math.inf), "3 px and over": (3, math.inf)}
    for band, (low, high) in bands.items():
        in_band = [r for r in on if r["true_px"] is not None and low <= r["true_px"] < high]
        measured = [r for r in in_band if r["max_mm"] is not None]
        errors = np.array([(r["max_mm"] - r["true_mm"]) / r["true_mm"] for r in measured])
        if len(errors):
            print(f"| {band} | {len(in_band)} | {len(measured)} | {np.median(np.abs(errors)):.0%} | "
                  f"{np.median(errors):+.0%} | {np.percentile(np.abs(errors), 90):.0%} |")
        else:
            print(f"| {band} | {len(in_band)} | 0 | - | - | - |")
    wide = [r for r in on if r["true_px"] is not None and r["true_px"] >= WIDE_PX and r["max_mm"] is not None]
    if wide:
        ratios = np.array([r["max_mm"] / r["true_mm"] for r in wide])
        print(f"cracks {WIDE_PX:g} px and wider on their masks: {len(wide)}, widest over the mask's: median "
              f"{np.median(ratios):.2f}, under half of it {np.mean(ratios < 0.5):.0%} ({np.sum(ratios < 0.5)})")
        stretch = np.array([r["max_mm"] / r["true_stretch_mm"] for r in wide if r["true_stretch_mm"]])
        print(f"  widest over the mask's widest stretch ({STRETCH_PX:g} px along its axis, none within "
              f"{FORK_PX:g} px of a junction): median {np.median(stretch):.2f}, "
              f"under half of it {np.mean(stretch < 0.5):.0%} ({np.sum(stretch < 0.5)})")
        medians = np.array([r["median_mm"] / r["true_median_mm"] for r in wide if r["median_mm"] and r["true_median_mm"]])
        print(f"  median along the crack over the mask's median width along it: median {np.median(medians):.2f}, "
              f"under half of it {np.mean(medians < 0.5):.0%} ({np.sum(medians < 0.5)})")
        print("the ten furthest under their masks (photo, candidate, mask px, read px, method, fit):")
        for r in sorted(wide, key=lambda r: r["max_mm"] / r["true_mm"])[:10]:
            print(f"  {r['photo']} {r['id']}: mask {r['true_px']:.1f} px, read {r['max_mm'] / r['true_mm'] * r['true_px']:.1f} px"
                  f" ({r['method']}, {r['fit']})")
    judged = [r for r in on if r["true_mm"] is not None]
    right = sum(r["state"] == state(r["true_mm"]) for r in judged)
    none = sum(r["state"] is None for r in judged)
    print(f"condition state right for {right} of {len(judged)} candidates on cracks "
          f"({right / max(len(judged), 1):.0%}); {none} without one")
    confusion = {}
    for r in judged:
        key = (state(r["true_mm"]), r["state"])
        confusion[key] = confusion.get(key, 0) + 1
    print("states (true -> measured): " + ", ".join(f"{a}->{b}: {n}" for (a, b), n in sorted(confusion.items(), key=str)))
    order = sorted(rows, key=lambda r: -r["priority"])
    half = len(order) // 2
    if half:
        first = sum(r["on"] for r in order[:half]) / half
        second = sum(r["on"] for r in order[half:]) / (len(order) - half)
        distinct = len({round(r["confidence"], 6) for r in rows})
        print(f"review order: precision {first:.2f} in the first half, {second:.2f} in the second "
              f"({distinct} distinct confidences)")
    return rows


def pair(fine, coarse):
    (_, _, a), (_, _, b) = fine, coarse
    both = agree = 0
    ratios = []
    for r in a:
        if r["max_mm"] is None or not r["on"]:
            continue
        matches = [s for s in b if s["photo"] == r["photo"] and s["max_mm"] is not None
                   and np.mean(np.min(np.linalg.norm(s["pts"][:, None] - r["pts"][None, ::4], axis=2), axis=1) <= 8.0) >= 0.5]
        if not matches:
            continue
        s = max(matches, key=lambda s: len(s["pts"]))
        both += 1
        ratios.append(s["max_mm"] / r["max_mm"])
        if abs(s["max_mm"] - r["max_mm"]) <= (r["uncertainty_mm"] or 0) + (s["uncertainty_mm"] or 0):
            agree += 1
    print(f"\n## the same cracks at two GSDs: {both} measured in both, widths agree within their "
          f"uncertainties for {agree} ({agree / max(both, 1):.0%}); coarse over fine: median "
          f"{np.median(ratios) if ratios else float('nan'):.2f}")


def score(args):
    if len(args.runs) % 2:
        sys.exit("real_cracks score: give FLIGHT RUN pairs")
    for flight, run in zip(args.runs[::2], args.runs[1::2]):
        report(flight, run)
    if args.pair:
        pair(scored_run(*args.pair[:2]), scored_run(*args.pair[2:]))


def darkness(args):
    """How dark real cracks are for their width: at points along each
    mask's medial axis, the darkness summed across the crack (grey levels
    below the surface's, sampled every quarter pixel out to 10 px on the
    axis's normal; the surface the median beyond 7 px) over the surface's
    brightness and the drawn width, by that width. A crack `w` px wide
    whose interior lacks a share `C` of the light sums to `C w`: this is
    the `C` the darkness integral assumes (`--crack-darkness`)."""
    from scipy import ndimage
    from scipy.spatial import cKDTree

    t = np.arange(-10, 10.001, 0.25)
    shares = []
    for photo in photos_in(args.photos, args.limit):
        truth = truth_of(str(photo))
        gray = np.asarray(Image.open(photo).convert("L"), dtype=float)
        axis = truth.skeleton[::SUB * 3]
        if len(axis) < 2:
            continue
        tree = cKDTree(truth.skeleton)
        for x, y in axis:
            near = truth.skeleton[tree.query_ball_point([x, y], 4.0)]
            if len(near) < 4:
                continue
            _, _, vt = np.linalg.svd(near - near.mean(axis=0))
            nx, ny = -vt[0][1], vt[0][0]
            grey = ndimage.map_coordinates(gray, [y + t * ny, x + t * nx], order=1, mode="nearest")
            drawn = ndimage.map_coordinates(truth.on.astype(float), [y + t * ny, x + t * nx], order=0)
            surface = np.median(grey[np.abs(t) >= 7])
            width = drawn.sum() * 0.25
            if surface > 0 and width > 0:
                shares.append((width, np.clip(surface - grey, 0, None).sum() * 0.25 / (surface * width)))
    shares = np.array(shares)
    print("| drawn width | points | darkness summed over surface x width, median |")
    print("|---|---|---|")
    for low, high in [(1, 3), (3, 5), (5, 7), (7, 10), (10, 15)]:
        band = shares[(shares[:, 0] >= low) & (shares[:, 0] < high)]
        if len(band):
            print(f"| {low}-{high} px | {len(band)} | {np.median(band[:, 1]):.2f} |")


def half_depths(grey, pts, mask_px):
    """Widths at half, a quarter and a tenth of the depth of the profiles
    across trace `pts` (photo pixels) in `grey`, every third point: the
    surface the median of the profile from three quarters of its reach out
    (the reach three mask widths, 20 px at least), the depth the darkest
    within the mask's half width and 2 px of the line."""
    from scipy import ndimage

    reach = max(3.0 * mask_px, 20.0)
    t = np.arange(-reach, reach + 0.25, 0.5)
    widths = []
    for i in range(4, len(pts) - 4, 3):
        d = pts[i + 4] - pts[i - 4]
        if not np.linalg.norm(d):
            continue
        d = d / np.linalg.norm(d)
        xy = pts[i][None, :] + t[:, None] * np.array([-d[1], d[0]])[None, :]
        profile = ndimage.map_coordinates(grey, [xy[:, 1], xy[:, 0]], order=1, mode="nearest")
        surface = np.median(profile[np.abs(t) > 0.75 * reach])
        k = int(np.argmin(np.where(np.abs(t) <= mask_px / 2 + 2, profile, np.inf)))
        depth = surface - profile[k]
        if depth <= 10:
            continue
        row = []
        for share in (0.5, 0.25, 0.1):
            level = surface - share * depth
            lo = hi = k
            while lo > 0 and profile[lo] < level:
                lo -= 1
            while hi < len(profile) - 1 and profile[hi] < level:
                hi += 1
            row.append((hi - lo) * 0.5)
        widths.append(row)
    return np.array(widths)


def profiles(args):
    """Of the cracks 6 px and wider on their masks that a run measured,
    the photo's own grey levels: each crack's median width along it at
    half, a quarter and a tenth of its profiles' depth below the surface
    a few mask widths out (`half_depths`), and postflight's median, each
    over the mask's median along the crack: whether a crack read under
    half its mask shows that narrower line in the photo."""
    photos, _, rows = scored_run(args.flight, args.run)
    path = {Path(f["photo"]).name: f["photo"] for f in photos["frames"]}
    out = []
    for r in rows:
        if not (r["on"] and r["true_px"] and r["true_px"] >= WIDE_PX and r["median_mm"] and r["true_median_mm"]):
            continue
        grey = np.asarray(Image.open(path[r["photo"]]).convert("L"), dtype=float)
        widths = half_depths(grey, r["pts"], r["true_px"])
        if not len(widths):
            continue
        mask = r["true_median_mm"] / r["true_mm"] * r["true_px"]
        out.append((r["photo"], r["id"], mask, r["median_mm"] / r["true_mm"] * r["true_px"], *np.median(widths, axis=0)))
    out.sort(key=lambda o: o[3] / o[2])
    print("| photo | candidate | mask, median px | postflight's median | half depth | quarter | tenth |")
    print("|---|---|---|---|---|---|---|")
    for o in out[: args.most]:
        print("| %s | %s | %.1f | %.1f | %.1f | %.1f | %.1f |" % o)
    a = np.array([o[2:] for o in out])
    for j, name in ((1, "postflight's median"), (2, "half depth"), (3, "quarter depth"), (4, "tenth depth")):
        ratio = a[:, j] / a[:, 0]
        print(f"{name} over the mask's median: median {np.median(ratio):.2f}, under half {np.sum(ratio < 0.5)} of {len(ratio)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    w = sub.add_parser("write")
    w.add_argument("--photos", required=True)
    w.add_argument("--gsd", type=float, required=True, help="millimetres per pixel")
    w.add_argument("--out", required=True)
    w.add_argument("--limit", type=int, default=0)
    w.add_argument("--downsample", type=int, default=1)
    s = sub.add_parser("score")
    s.add_argument("runs", nargs="+")
    s.add_argument("--pair", nargs=4, metavar=("FINE_FLIGHT", "FINE_RUN", "COARSE_FLIGHT", "COARSE_RUN"))
    d = sub.add_parser("darkness")
    d.add_argument("--photos", required=True)
    d.add_argument("--limit", type=int, default=0)
    p = sub.add_parser("profiles")
    p.add_argument("flight")
    p.add_argument("run")
    p.add_argument("--most", type=int, default=12, help="cracks listed, furthest under their masks first")
    args = ap.parse_args()
    {"write": write, "score": score, "darkness": darkness, "profiles": profiles}[args.command](args)


if __name__ == "__main__":
    main()
