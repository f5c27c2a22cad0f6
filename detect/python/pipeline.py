#!/usr/bin/env python3
"""The detect stage written as a plain Python onnxruntime + NumPy + Pillow
script, the way a YOLO-World user would: the independent reference that
postflight's Rust pipeline is checked against (tests/detect.rs) and the
baseline its speed is compared with (postflight-bench detect).

It reads camera frames straight from the flight MCAP, and mirrors the Rust
pre- and post-processing step by step in float32: Ultralytics letterbox with
OpenCV INTER_LINEAR pixel-centre bilinear resizing rounded to 8 bits, gray
114 padding (for a dynamic input, the smallest rectangle padded to the
model's stride, as Ultralytics' LetterBox(auto=True)), optional tiles, best
class per anchor, class-aware NMS (ties broken by position), then merging
same-class boxes within --merge-gap px, boxes clipped to the frame last. A
semantic segmentation model (one output [B, 1 or 2, H, W]) gives its
connected crack regions (8-neighbours, probability above 0.5, at least 8
pixels) as boxes scored by their mean probability.

Writes JSON: {"frames": n, "seconds": s, "run_seconds": s,
"detections": [{"time_ns", "x0", "y0", "x1", "y1", "score", "class", "tile"}]}.

Run: .venv/bin/python detect/python/pipeline.py FLIGHT.mcap MODEL.onnx OUT.json
"""

import argparse
import io
import json
import math
import sys
import time

import numpy as np
import onnxruntime as ort
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from PIL import Image

F = np.float32
PAD = 114


def decode_image(msg):
    """RGB uint8 array of a CompressedImage (jpeg/png) or a raw rgb8/bgr8/mono8 Image."""
    if hasattr(msg, "format"):
        return np.asarray(Image.open(io.BytesIO(bytes(msg.data))).convert("RGB"))
    h, w, step = msg.height, msg.width, msg.step
    rows = np.frombuffer(bytes(msg.data), np.uint8).reshape(h, step)
    if msg.encoding == "mono8":
        return np.repeat(rows[:, :w, None], 3, axis=2)
    img = rows[:, : 3 * w].reshape(h, w, 3)
    if msg.encoding == "bgr8":
        return img[:, :, ::-1].copy()
    if msg.encoding == "rgb8":
        return img
    sys.exit(f"pipeline.py: raw encoding {msg.encoding} is not supported")


def windows(width, height, tile, overlap):
    """The whole frame, then square tiles: (x, y, w, h, tile)."""
    out = [(0, 0, width, height, -1)]
    if tile is None or tile >= max(width, height):
        return out

    def starts(n):
        if n <= tile:
            return [0]
        step = max(int(math.floor(F(tile) * (F(1.0) - F(overlap)))), 1)
        s = [k * step for k in range(n) if k * step + tile < n]
        return s + [n - tile]

    for y in starts(height):
        for x in starts(width):
            out.append((x, y, min(tile, width), min(tile, height), len(out) - 1))
    return out


def taps(src, dst):
    """Bilinear taps (i0, i1, weight of i1) with OpenCV INTER_LINEAR centres."""
    scale = F(src) / F(dst)
    s = (np.arange(dst, dtype=F) + F(0.5)) * scale - F(0.5)
    s = np.clip(s, F(0), F(src - 1))
    i = np.floor(s)
    i0 = i.astype(np.int64)
    return i0, np.minimum(i0 + 1, src - 1), (s - i).astype(F)


def letterbox(img, size_w, size_h, stride):
    """[3, H, W] float32 input and (scale, pad_x, pad_y) for a size_w x size_h
    input, or with a stride (dynamic input) the smallest rectangle within it."""
    h, w = img.shape[:2]
    scale = min(F(size_w) / F(w), F(size_h) / F(h))
    # Rust's f32::round: half away from zero.
    new_w = max(int(math.floor(float(F(w) * scale) + 0.5)), 1)
    new_h = max(int(math.floor(float(F(h) * scale) + 0.5)), 1)
    if stride is not None:
        size_w = new_w + max(size_w - new_w, 0) % stride
        size_h = new_h + max(size_h - new_h, 0) % stride
    pad_x, pad_y = max(size_w - new_w, 0) // 2, max(size_h - new_h, 0) // 2
    if (new_w, new_h) == (w, h):
        resized = img
    else:
        x0, x1, fx = taps(w, new_w)
        y0, y1, fy = taps(h, new_h)
        src = img.astype(F)
        fx = fx[None, :, None]
        rows = lambda y: src[y][:, x0] * (F(1) - fx) + src[y][:, x1] * fx  # noqa: E731
        fy = fy[:, None, None]
        v = rows(y0) * (F(1) - fy) + rows(y1) * fy
        resized = np.clip(np.floor(v + F(0.5)), 0, 255).astype(np.uint8)
    out = np.full((3, size_h, size_w), F(PAD) / F(255), dtype=F)
    out[:, pad_y : pad_y + new_h, pad_x : pad_x + new_w] = resized.transpose(2, 0, 1).astype(F) / F(255)
    return out, (scale, F(pad_x), F(pad_y))


def area(b):
    return max(b[2] - b[0], F(0)) * max(b[3] - b[1], F(0))


def iou(a, b):
    inter = area((max(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), min(a[3], b[3])))
    union = area(a) + area(b) - inter
    return F(0) if union <= 0 else inter / union


def nms(dets, threshold):
    dets = sorted(dets, key=lambda d: (-d["score"], d["box"][0], d["box"][1]))
    kept = []
    for d in dets:
        if all(k["class"] != d["class"] or iou(k["box"], d["box"]) <= threshold for k in kept):
            kept.append(d)
    return kept


MERGE_SCORE_RATIO = F(0.5)  # as detect/src/boxes.rs


def merge_touching(dets, gap):
    def near(a, b):
        return a[0] <= b[2] + gap and b[0] <= a[2] + gap and a[1] <= b[3] + gap and b[1] <= a[3] + gap

    def comparable(a, b):
        return min(a["score"], b["score"]) >= MERGE_SCORE_RATIO * max(a["score"], b["score"])

    merged = True
    while merged:
        merged = False
        for i in range(len(dets)):
            for j in range(i + 1, len(dets)):
                a, b = dets[i], dets[j]
                if a["class"] == b["class"] and near(a["box"], b["box"]) and comparable(a, b):
                    dets[i] = {
                        "box": tuple(f(p, q) for f, p, q in zip((min, min, max, max), a["box"], b["box"])),
                        "score": max(a["score"], b["score"]),
                        "class": a["class"],
                        "tile": a["tile"] if a["score"] >= b["score"] else b["tile"],
                    }
                    dets[j] = dets[-1]  # swap_remove, as the Rust code does
                    dets.pop()
                    merged = True
                    break
            if merged:
                break
    return dets


def boxes_of(out, conf, input_width):
    """(box in model input pixels, score, class) of one image's output: YOLO
    rows [4 + nc, anchors], or a semantic map [1 or 2, H, W]."""
    if out.ndim == 2:
        cls = np.argmax(out[4:], axis=0)
        score = out[4:][cls, np.arange(out.shape[1])]
        for a in np.nonzero(score >= conf)[0]:
            cx, cy, bw, bh = out[:4, a]
            yield (cx - bw / F(2), cy - bh / F(2), cx + bw / F(2), cy + bh / F(2)), score[a], int(cls[a])
        return
    sigmoid = lambda v: F(1) / (F(1) + np.exp(-v))
    if out.shape[0] == 2:
        p = sigmoid(out[1] - out[0])
    elif out.min() < 0 or out.max() > 1:
        p = sigmoid(out[0])
    else:
        p = out[0]
    stride = F(input_width) / F(p.shape[1])
    for (x0, y0, x1, y1), score in components(p > F(0.5), p, 8):
        if score >= conf:
            yield (F(x0) * stride, F(y0) * stride, F(x1) * stride, F(y1) * stride), score, 0


def components(on, p, min_pixels):
    """Connected regions (8-neighbours) of `on`: box (exclusive edges) and mean `p`."""
    h, w = on.shape
    seen = np.zeros_like(on)
    for y0, x0 in zip(*np.nonzero(on)):
        if seen[y0, x0]:
            continue
        seen[y0, x0] = True
        stack, pixels = [(y0, x0)], []
        while stack:
            y, x = stack.pop()
            pixels.append((y, x))
            for ny in range(max(y - 1, 0), min(y + 2, h)):
                for nx in range(max(x - 1, 0), min(x + 2, w)):
                    if on[ny, nx] and not seen[ny, nx]:
                        seen[ny, nx] = True
                        stack.append((ny, nx))
        if len(pixels) >= min_pixels:
            ys, xs = zip(*pixels)
            mean = F(np.mean(np.array([p[y, x] for y, x in pixels], dtype=np.float64)))
            yield (min(xs), min(ys), max(xs) + 1, max(ys) + 1), mean


def text_input(path, prompts, nc, dim):
    table = json.load(open(path))
    rows = []
    for p in prompts:
        v = np.asarray(table[p], dtype=F)
        rows.append(v / np.sqrt(np.sum(v * v, dtype=F)))
    n = nc if isinstance(nc, int) else len(prompts)
    x = np.zeros((1, n, dim), dtype=F)
    x[0, : len(rows)] = np.stack(rows)
    return x


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("flight")
    ap.add_argument("model")
    ap.add_argument("out")
    ap.add_argument("--topic", default="/camera/image_raw/compressed")
    ap.add_argument("--embeddings")
    ap.add_argument("--prompt", action="append")
    ap.add_argument("--confidence", type=float, default=0.25)
    ap.add_argument("--iou", type=float, default=0.5)
    ap.add_argument("--merge-gap", default="20", help="pixels, or 'off'")
    ap.add_argument("--imgsz", type=int, default=640)
    ap.add_argument("--tile", type=int)
    ap.add_argument("--tile-overlap", type=float, default=0.2)
    args = ap.parse_args()

    start = time.perf_counter()
    session = ort.InferenceSession(args.model, providers=["CPUExecutionProvider"])
    inputs = session.get_inputs()
    image_input = next(i for i in inputs if len(i.shape) == 4)
    h, w = image_input.shape[2:]
    if isinstance(w, int) and isinstance(h, int):
        size_w, size_h, stride = w, h, None
    else:
        size_w, size_h = args.imgsz, args.imgsz
        stride = int(session.get_modelmeta().custom_metadata_map.get("stride", 32))
    feeds = {}
    text = [i for i in inputs if i.name != image_input.name]
    if text:
        nc, dim = text[0].shape[1:]
        feeds[text[0].name] = text_input(args.embeddings, args.prompt or ["crack"], nc, dim)
    conf, iou_threshold = F(args.confidence), F(args.iou)

    found, frames, run_seconds = [], 0, 0.0
    with open(args.flight, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for _, _, _, msg in reader.iter_decoded_messages(topics=[args.topic]):
            stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            img = decode_image(msg)
            height, width = img.shape[:2]
            dets = []
            for x, y, ww, wh, tile in windows(width, height, args.tile, args.tile_overlap):
                x_in, (scale, pad_x, pad_y) = letterbox(img[y : y + wh, x : x + ww], size_w, size_h, stride)
                t = time.perf_counter()
                out = session.run(None, {image_input.name: x_in[None], **feeds})[0][0]
                run_seconds += time.perf_counter() - t
                offset = (x, y, x, y)
                pad = (pad_x, pad_y, pad_x, pad_y)
                for box, score, cls in boxes_of(out, conf, x_in.shape[2]):
                    box = tuple((v - p) / scale + F(o) for v, p, o in zip(box, pad, offset))
                    dets.append({"box": box, "score": score, "class": cls, "tile": tile})
            lim = (width, height, width, height)
            clip = lambda b: tuple(np.clip(v, F(0), F(m)) for v, m in zip(b, lim))
            dets = [d for d in dets if area(clip(d["box"])) > 0]
            kept = nms(dets, iou_threshold)
            if args.merge_gap != "off":
                kept = merge_touching(kept, F(args.merge_gap))
            for d in kept:
                x0, y0, x1, y1 = (float(v) for v in clip(d["box"]))
                found.append(
                    {
                        "time_ns": stamp,
                        "x0": x0,
                        "y0": y0,
                        "x1": x1,
                        "y1": y1,
                        "score": float(d["score"]),
                        "class": d["class"],
                        "tile": d["tile"],
                    }
                )
            frames += 1
    seconds = time.perf_counter() - start
    result = {"frames": frames, "seconds": seconds, "run_seconds": run_seconds, "detections": found}
    json.dump(result, open(args.out, "w"))


if __name__ == "__main__":
    main()
