#!/usr/bin/env python3
"""Build postflight's reference crack detectors as real ONNX graphs.

No trained weights can be downloaded where postflight is built, so these
small hand-designed networks stand in for a YOLO-World export. They keep
YOLO-World's interfaces exactly, so the same pipeline runs either:

- crack-baked.onnx: input `images` [B, 3, H, W] (RGB 0..1, letterboxed),
  output `output0` [B, 5, N] = (cx, cy, w, h, score) per 16-pixel cell, with
  the vocabulary ("crack") baked in, as Ultralytics exports after
  `set_classes(["crack"])`;
- crack-open.onnx: the same image input plus `txt_feats` [1, nc, 512] text
  embeddings; output [B, 4 + nc, N], the crack score scaled by each prompt
  embedding's similarity to this model's own "crack" direction (see
  prompts.json; these are not CLIP features).

The network: grey = luma of the image; for 4 orientations, how much darker a
3-pixel stroke is than both of its sides 2-3 pixels away, less how much the
sides differ (so thin dark lines on one surface respond, and edges and dark
lines between different surfaces do not); the strongest
orientation, through a sigmoid, is a per-pixel crack score. Each 16-pixel
cell reports its best score and the box of the crack pixels in the 48-pixel
window around it.

Run: .venv/bin/python detect/models/build_reference.py detect/models
"""

import json
import math
import os
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

STRIDE = 16
WINDOW = 3 * STRIDE
THRESHOLD = 0.09  # stroke darkness (0..1 image units) at which the score is 0.5
MIN_EXTENT = 8.0  # pixels: shorter dark specks are noise, not cracks
GAIN = 80.0
EMBED_DIM = 512
PROMPTS = ["crack", "spalling", "corrosion", "stain", "vegetation", "graffiti"]


def line_kernels():
    """[8, 1, 7, 7]: for each orientation, (side A mean - stroke mean) and (side B mean - stroke mean)."""
    kernels = []
    for angle in (0, 45, 90, 135):
        a = math.radians(angle)
        d = (math.cos(a), math.sin(a))  # along the stroke (x right, y down)
        n = (-d[1], d[0])  # across it
        for side in (1, -1):
            k = np.zeros((7, 7), dtype=np.float32)
            for t in (-1, 0, 1):
                cx, cy = round(3 + t * d[0]), round(3 + t * d[1])
                k[cy, cx] -= 1.0 / 3.0
                for s in (2, 3):
                    x = round(3 + t * d[0] + side * s * n[0])
                    y = round(3 + t * d[1] + side * s * n[1])
                    k[y, x] += 1.0 / 6.0
            kernels.append(k)
    return np.stack(kernels)[:, None, :, :]


def crack_direction():
    rng = np.random.default_rng(20261121)
    v = rng.standard_normal(EMBED_DIM).astype(np.float32)
    return v / np.linalg.norm(v)


def prompt_embeddings():
    """Unit vectors for the prompts: "crack" is the model's crack direction."""
    rng = np.random.default_rng(7)
    crack = crack_direction()
    out = {}
    for name in PROMPTS:
        if name == "crack":
            v = crack
        else:
            v = rng.standard_normal(EMBED_DIM).astype(np.float32)
            v -= v.dot(crack) * crack  # unrelated to cracks
            v /= np.linalg.norm(v)
        out[name] = v
    return out


def const(name, array):
    return numpy_helper.from_array(np.asarray(array), name)


def backbone(nodes, inits):
    """Nodes from `images` to `score` [B,1,N] and `boxes` [B,4,N]."""
    inits += [
        const("w_gray", np.array([0.299, 0.587, 0.114], dtype=np.float32).reshape(1, 3, 1, 1)),
        const("w_line", line_kernels()),
        const("c0", np.array([0], dtype=np.int64)),
        const("c1", np.array([1], dtype=np.int64)),
        const("c8", np.array([8], dtype=np.int64)),
        const("c2", np.array([2], dtype=np.int64)),
        const("threshold", np.array(THRESHOLD, dtype=np.float32)),
        const("gain", np.array(GAIN, dtype=np.float32)),
        const("half", np.array(0.5, dtype=np.float32)),
        const("big", np.array(1e6, dtype=np.float32)),
        const("one", np.array(1.0, dtype=np.float32)),
        const("two", np.array(2.0, dtype=np.float32)),
        const("min_extent", np.array(MIN_EXTENT, dtype=np.float32)),
        const("i0", np.array(0, dtype=np.int64)),
        const("i1", np.array(1, dtype=np.int64)),
        const("i2", np.array([2], dtype=np.int64)),
        const("i3", np.array([3], dtype=np.int64)),
        const("row_shape", np.array([1, 1, 1, -1], dtype=np.int64)),
        const("col_shape", np.array([1, 1, -1, 1], dtype=np.int64)),
        const("out_shape", np.array([0, 1, -1], dtype=np.int64)),
        const("box_shape", np.array([0, 4, -1], dtype=np.int64)),
    ]
    n = helper.make_node
    nodes += [
        n("Conv", ["images", "w_gray"], ["gray"]),
        n("Conv", ["gray", "w_line"], ["sides"], pads=[3, 3, 3, 3]),
        # Even channels are side A, odd side B. A crack is darker than both
        # sides, and its sides are alike (one surface): 2 min - max penalises
        # a dark line between different surfaces (a pole against the sky).
        n("Slice", ["sides", "c0", "c8", "c1", "c2"], ["side_a"]),
        n("Slice", ["sides", "c1", "c8", "c1", "c2"], ["side_b"]),
        n("Min", ["side_a", "side_b"], ["side_min"]),
        n("Max", ["side_a", "side_b"], ["side_max"]),
        n("Mul", ["side_min", "two"], ["side_min2"]),
        n("Sub", ["side_min2", "side_max"], ["stroke"]),
        n("ReduceMax", ["stroke", "i1_axes"], ["line"], keepdims=1),
        n("Sub", ["line", "threshold"], ["line_t"]),
        n("Mul", ["line_t", "gain"], ["line_g"]),
        n("Sigmoid", ["line_g"], ["pixel_score"]),
        n("MaxPool", ["pixel_score"], ["cell_score"], kernel_shape=[STRIDE, STRIDE], strides=[STRIDE, STRIDE]),
        # Pixel coordinates (centres) as [1, 1, 1, W] and [1, 1, H, 1].
        n("Shape", ["gray"], ["shape"]),
        n("Gather", ["shape", "i2"], ["h1"]),
        n("Gather", ["shape", "i3"], ["w1"]),
        n("Squeeze", ["h1"], ["h"]),
        n("Squeeze", ["w1"], ["w"]),
        n("Range", ["i0", "w", "i1"], ["xs_i"]),
        n("Range", ["i0", "h", "i1"], ["ys_i"]),
        n("Cast", ["xs_i"], ["xs_f"], to=TensorProto.FLOAT),
        n("Cast", ["ys_i"], ["ys_f"], to=TensorProto.FLOAT),
        n("Reshape", ["xs_f", "row_shape"], ["xs"]),
        n("Reshape", ["ys_f", "col_shape"], ["ys"]),
        # Crack pixels: score above one half.
        n("Greater", ["pixel_score", "half"], ["active_b"]),
        n("Cast", ["active_b"], ["active"], to=TensorProto.FLOAT),
        n("Sub", ["one", "active"], ["inactive"]),
        n("Mul", ["inactive", "big"], ["far"]),
    ]
    # max over the window of v on crack pixels, -big elsewhere
    for name, coord, sign in (("x1", "xs", 1), ("y1", "ys", 1), ("x0", "xs", -1), ("y0", "ys", -1)):
        signed = coord if sign > 0 else f"neg_{coord}"
        if sign < 0 and not any(node.output[0] == signed for node in nodes):
            nodes.append(n("Neg", [coord], [signed]))
        nodes += [
            n("Mul", [signed, "active"], [f"{name}_on"]),
            n("Sub", [f"{name}_on", "far"], [f"{name}_masked"]),
            n("MaxPool", [f"{name}_masked"], [f"{name}_pool"], kernel_shape=[WINDOW, WINDOW],
              strides=[STRIDE, STRIDE], pads=[STRIDE, STRIDE, STRIDE, STRIDE]),
        ]
    nodes += [
        n("Neg", ["x0_pool"], ["x0"]),
        n("Neg", ["y0_pool"], ["y0"]),
        n("Add", ["x1_pool", "one"], ["x1"]),
        n("Add", ["y1_pool", "one"], ["y1"]),
        n("Add", ["x0", "x1"], ["cx2"]),
        n("Add", ["y0", "y1"], ["cy2"]),
        n("Div", ["cx2", "two"], ["cx"]),
        n("Div", ["cy2", "two"], ["cy"]),
        n("Sub", ["x1", "x0"], ["bw"]),
        n("Sub", ["y1", "y0"], ["bh"]),
        # Cells with no crack pixels nearby, or only a speck, have no box: score 0.
        n("Max", ["bw", "bh"], ["extent"]),
        n("Greater", ["extent", "min_extent"], ["has_box_b"]),
        n("Cast", ["has_box_b"], ["has_box"], to=TensorProto.FLOAT),
        n("Mul", ["cell_score", "has_box"], ["score_grid"]),
        n("Concat", ["cx", "cy", "bw", "bh"], ["box_grid"], axis=1),
        n("Reshape", ["box_grid", "box_shape"], ["boxes"]),
        n("Reshape", ["score_grid", "out_shape"], ["score"]),
    ]
    inits.append(const("i1_axes", np.array([1], dtype=np.int64)))


def metadata(model, names):
    for key, value in {
        "description": "postflight reference crack detector (hand-designed thin-dark-line network, not trained)",
        "author": "postflight",
        "stride": str(STRIDE),
        "task": "detect",
        "names": "{" + ", ".join(f"{i}: '{n}'" for i, n in enumerate(names)) + "}",
    }.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value


def save(nodes, inits, inputs, outputs, path, names):
    graph = helper.make_graph(nodes, "postflight_crack_reference", inputs, outputs, inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)], producer_name="postflight")
    model.ir_version = 8
    metadata(model, names)
    onnx.checker.check_model(model, full_check=True)
    onnx.save(model, path)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
    images = helper.make_tensor_value_info("images", TensorProto.FLOAT, ["batch", 3, "height", "width"])

    nodes, inits = [], []
    backbone(nodes, inits)
    nodes.append(helper.make_node("Concat", ["boxes", "score"], ["output0"], axis=1))
    output = helper.make_tensor_value_info("output0", TensorProto.FLOAT, ["batch", 5, "anchors"])
    save(nodes, inits, [images], [output], os.path.join(out, "crack-baked.onnx"), ["crack"])

    nodes, inits = [], []
    backbone(nodes, inits)
    inits.append(const("crack_direction", crack_direction().reshape(EMBED_DIM, 1)))
    inits.append(const("zero", np.array(0.0, dtype=np.float32)))
    n = helper.make_node
    nodes += [
        # [1, nc, 512] x [512, 1] -> [1, nc, 1]: each prompt's likeness to "crack", clipped to 0..1.
        n("MatMul", ["txt_feats", "crack_direction"], ["likeness"]),
        n("Clip", ["likeness", "zero", "one"], ["relevance"]),
        n("Mul", ["score", "relevance"], ["class_scores"]),
        n("Concat", ["boxes", "class_scores"], ["output0"], axis=1),
    ]
    txt = helper.make_tensor_value_info("txt_feats", TensorProto.FLOAT, [1, "classes", EMBED_DIM])
    output = helper.make_tensor_value_info("output0", TensorProto.FLOAT, ["batch", "rows", "anchors"])
    save(nodes, inits, [images, txt], [output], os.path.join(out, "crack-open.onnx"), ["crack"])

    with open(os.path.join(out, "prompts.json"), "w") as f:
        json.dump({name: [round(float(x), 7) for x in v] for name, v in prompt_embeddings().items()}, f)


if __name__ == "__main__":
    main()
