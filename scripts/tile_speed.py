"""What tiling costs with a fixed-size model: its speed on the tiles of a
20 MP photo (5472 x 3648 in 256 px tiles overlapping by a fifth, as
postflight's `tile = "auto"` runs a 256 x 256 model), against the one
inference of the photo shrunk to the input, with ONNX Runtime on the CPU
at 1, 4 and every thread. BENCHMARKS.md quotes it.

    .venv/bin/python scripts/tile_speed.py MODEL.onnx
"""
import os, sys, time, json
import numpy as np, onnxruntime as ort

def starts(n, size, overlap):
    if n <= size: return [0]
    step = max(int(size * (1 - overlap)), 1)
    out = [k * step for k in range(n) if k * step + size < n]
    return out + [n - size]

W, H = 5472, 3648
tiles = len(starts(W, 256, 0.2)) * len(starts(H, 256, 0.2))
model = sys.argv[1]
rng = np.random.default_rng(1)
x = (rng.random((1, 3, 256, 256), dtype=np.float32) * 255).astype(np.float32)
res = {"tiles_per_photo": tiles, "whole_frame_inferences": 1, "cpus": os.cpu_count(), "ort": ort.__version__}
for threads in (1, 4, os.cpu_count()):
    o = ort.SessionOptions(); o.intra_op_num_threads = threads
    s = ort.InferenceSession(model, o, providers=["CPUExecutionProvider"])
    name = s.get_inputs()[0].name
    for _ in range(3): s.run(None, {name: x})
    n = 40; t = time.perf_counter()
    for _ in range(n): s.run(None, {name: x})
    per = (time.perf_counter() - t) / n
    res[f"s_per_tile_{threads}_threads"] = per
    res[f"s_per_photo_{threads}_threads"] = per * tiles
res["tiles_over_whole_frame"] = tiles
print(json.dumps(res, indent=1))
