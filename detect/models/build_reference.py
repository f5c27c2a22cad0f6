#!/usr/bin/env python3
"""Build postflight's reference crack detectors as real ONNX graphs.

No trained weights can be downloaded where postflight is built, so these
small hand-designed networks stand in for a YOLO-World export. They keep
YOLO-World's interfaces exactly, so the same pipeline runs either:

- crack-baked.onnx: input `images` [B, 3, H, W] (RGB 0..1, letterboxed),
  output `output0` [B, 5, N] = (cx, cy, w, h, score) per 16-pixel cell, with
  the vocabulary ("crack") baked in, as Ultralytics exports after
  `set_classes(["crack"])`, and `mask` [B, 1, H, W], the per-pixel crack
  score (the ridge response), as a segmentation network's probability map;
- crack-open.onnx: the same image input plus `txt_feats` [1, nc, 512] text
  embeddings; output [B, 4 + nc, N], the crack score scaled by each prompt
  embedding's similarity to this model's own "crack" direction (see
  prompts.json; these are not CLIP features), and the same `mask`;
- crack-semantic.onnx: a semantic segmentation network's interface, one
  output `logits` [B, 2, H, W] of background and crack (their softmax is the
  per-pixel crack score), as DeepCrack- or U-Net-style crack segmenters give;
- area-reference.onnx: an area-defect segmenter for the simulator's spalls,
  `logits` [B, 3, H, W] of background, spall and exposed_rebar, by colour
  (see area_network), run at 320 px (`postflight.train_px`).

The network: grey = luma of the image; for 8 orientations, how much darker a
7-pixel stroke is than both of its sides 2-3 pixels away, less how much the
sides differ, taking the weakest third of the stroke (so thin dark lines on
one surface respond, and edges, corners and specks do not), relative to the
surface's local brightness, less a penalty for colour (cracks are grey);
the strongest orientation, through a sigmoid, is a per-pixel crack score.
Each 16-pixel cell reports its best score and the box of the crack pixels in
the 48-pixel window around it; cells in texture (dense dark specks) and
cells whose box is shorter than MIN_EXTENT score 0.

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
ORIENTATIONS = 8
HALF_LENGTH = 3  # the stroke is 7 pixels long: corners and specks are shorter
SIDES = (2.0, 3.0)  # pixels across the stroke where its sides are sampled
KERNEL = 11
THRESHOLD = 0.11  # stroke darkness, relative to the surface's brightness, at which the score is 0.5
SURROUND = 15  # pixels: the window the surface's brightness is averaged over
SATURATION = 0.2  # cracks in concrete and steel are grey: saturation above this
SATURATION_WEIGHT = 2.0  # counts against the stroke's darkness, times this
DENSITY = 0.12  # share of crack pixels above which a window is texture
MIN_EXTENT = 20.0  # pixels: shorter dark marks are specks and edge ends, not cracks worth a finding
GAIN = 80.0
EMBED_DIM = 512
PROMPTS = ["crack", "spalling", "corrosion", "stain", "vegetation", "graffiti"]


def splat(k, x, y, w):
    """Add weight `w` at the sub-pixel point (x, y) of kernel `k`, bilinearly."""
    x0, y0 = math.floor(x), math.floor(y)
    fx, fy = x - x0, y - y0
    for dx, dy, f in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
        k[y0 + dy, x0 + dx] += w * f


def side_kernels():
    """[ORIENTATIONS * 3 * 2, K, K] (float64): for each orientation and each
    third of a stroke 2 * HALF_LENGTH + 1 pixels long (back, middle, front),
    the mean of side A less the stroke's mean, then the same for side B."""
    c = KERNEL // 2
    thirds = (range(-HALF_LENGTH, -1), range(-1, 2), range(2, HALF_LENGTH + 1))
    kernels = []
    for i in range(ORIENTATIONS):
        a = math.pi * i / ORIENTATIONS
        d = (math.cos(a), math.sin(a))  # along the stroke (x right, y down)
        n = (-d[1], d[0])  # across it
        for ts in thirds:
            for side in (1, -1):
                k = np.zeros((KERNEL, KERNEL), dtype=np.float64)
                for t in ts:
                    splat(k, c + t * d[0], c + t * d[1], -1.0 / len(ts))
                    for s in SIDES:
                        splat(k, c + t * d[0] + side * s * n[0], c + t * d[1] + side * s * n[1],
                              1.0 / (len(ts) * len(SIDES)))
                kernels.append(k)
    return np.stack(kernels)


def stroke_kernels():
    """[ORIENTATIONS * 6, 1, K, K]: per orientation and third, with a and b the
    two sides' contrast (side_kernels), 2a - b then 2b - a. A crack is darker
    than both sides and its sides are alike (one surface):
    2 min(a, b) - max(a, b) = min(2a - b, 2b - a) penalises a dark line
    between different surfaces (a pole against the sky). Being linear, both
    terms come straight out of the convolution, and one minimum over the six
    channels of an orientation takes both the sides and the weakest third."""
    k = side_kernels()
    a, b = k[0::2], k[1::2]
    out = np.empty_like(k)
    out[0::2], out[1::2] = 2 * a - b, 2 * b - a
    return out.astype(np.float32)[:, None, :, :]


def exact_dot(a, b):
    """a . b correctly rounded to float32: numpy's SIMD sums round differently
    on different CPUs, and the shipped models must rebuild byte for byte."""
    return np.float32(math.fsum(float(x) * float(y) for x, y in zip(a, b)))


def unit(v):
    return v / np.float32(math.sqrt(exact_dot(v, v)))


def crack_direction():
    rng = np.random.default_rng(20261121)
    return unit(rng.standard_normal(EMBED_DIM).astype(np.float32))


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
            v = unit(v - exact_dot(v, crack) * crack)  # unrelated to cracks
        out[name] = v
    return out


def const(name, array):
    return numpy_helper.from_array(np.asarray(array), name)


def backbone(nodes, inits):
    """Nodes from `images` to `score` [B,1,N] and `boxes` [B,4,N]."""
    inits += [
        const("w_gray", np.array([0.299, 0.587, 0.114], dtype=np.float32).reshape(1, 3, 1, 1)),
        const("w_line", stroke_kernels()),
        const("line_pads", np.array([0, 0, KERNEL // 2, KERNEL // 2, 0, 0, KERNEL // 2, KERNEL // 2], dtype=np.int64)),
        const("orientations_shape", np.array([0, ORIENTATIONS, 6, -1], dtype=np.int64)),
        const("saturation_w", np.array(SATURATION_WEIGHT, dtype=np.float32)),
        const("density_max", np.array(DENSITY, dtype=np.float32)),
        const("saturation_max", np.array(SATURATION, dtype=np.float32)),
        # Added to brightness before dividing by it, so black stays finite.
        const("dark_floor", np.array(0.05, dtype=np.float32)),
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
        # Edge padding: a crack at the frame's border is not darker than the
        # zeros beyond it.
        n("Pad", ["gray", "line_pads"], ["gray_padded"], mode="edge"),
        n("Conv", ["gray_padded", "w_line"], ["strokes"]),
        n("ReduceMax", ["images", "i1_axes"], ["rgb_max"], keepdims=1),
        n("ReduceMin", ["images", "i1_axes"], ["rgb_min"], keepdims=1),
        n("Sub", ["rgb_max", "rgb_min"], ["chroma_px"]),
        n("Add", ["rgb_max", "dark_floor"], ["value_f"]),
        n("Div", ["chroma_px", "value_f"], ["saturation_px"]),
        n("MaxPool", ["saturation_px"], ["saturation"], kernel_shape=[9, 9], pads=[4, 4, 4, 4]),
        n("Sub", ["saturation", "saturation_max"], ["saturation_over"]),
        n("Relu", ["saturation_over"], ["saturation_excess"]),
        n("Mul", ["saturation_excess", "saturation_w"], ["colour_penalty"]),
        # A line is dark along its whole length: the weakest third counts
        # (the corner of a dark object is dark along one third only).
        n("Reshape", ["strokes", "orientations_shape"], ["stroke_parts"]),
        n("ReduceMin", ["stroke_parts", "i2"], ["stroke_whole"], keepdims=0),
        n("ReduceMax", ["stroke_whole", "i1_axes"], ["line_flat"], keepdims=1),
        n("Shape", ["gray"], ["shape"]),
        n("Reshape", ["line_flat", "shape"], ["line_raw"]),
        n("Sub", ["line_raw", "colour_penalty"], ["line_abs"]),
        # Darkness relative to the surface: a crack is as visible on dark
        # steel as on bright concrete.
        n("AveragePool", ["gray"], ["surround_x"], kernel_shape=[1, SURROUND], pads=[0, SURROUND // 2, 0, SURROUND // 2], count_include_pad=0),
        n("AveragePool", ["surround_x"], ["surround"], kernel_shape=[SURROUND, 1], pads=[SURROUND // 2, 0, SURROUND // 2, 0], count_include_pad=0),
        n("Add", ["surround", "dark_floor"], ["surround_f"]),
        n("Div", ["line_abs", "surround_f"], ["line"]),
        n("Sub", ["line", "threshold"], ["line_t"]),
        n("Mul", ["line_t", "gain"], ["line_g"]),
        n("Sigmoid", ["line_g"], ["pixel_score"]),
        n("Identity", ["pixel_score"], ["mask"]),
        # Crack pixels: score above one half.
        n("Greater", ["pixel_score", "half"], ["active_b"]),
        n("Cast", ["active_b"], ["active"], to=TensorProto.FLOAT),
        # Texture (grass, gravel) is dark specks everywhere; a crack is a thin
        # curve through mostly clean surface.
        n("AveragePool", ["active"], ["cell_density"], kernel_shape=[STRIDE, STRIDE], strides=[STRIDE, STRIDE]),
        n("AveragePool", ["cell_density"], ["density"], kernel_shape=[3, 3], pads=[1, 1, 1, 1], count_include_pad=0),
        n("Less", ["density", "density_max"], ["sparse_b"]),
        n("Cast", ["sparse_b"], ["sparse"], to=TensorProto.FLOAT),
        n("MaxPool", ["pixel_score"], ["cell_best"], kernel_shape=[STRIDE, STRIDE], strides=[STRIDE, STRIDE]),
        n("Mul", ["cell_best", "sparse"], ["cell_score"]),
        # Pixel coordinates (centres) as [1, 1, 1, W] and [1, 1, H, 1].
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


def metadata(model, names, extra=None):
    for key, value in {
        "description": "postflight reference crack detector (hand-designed thin-dark-line network, not trained)",
        "author": "postflight",
        "stride": str(STRIDE),
        "task": "detect",
        "names": "{" + ", ".join(f"{i}: '{n}'" for i, n in enumerate(names)) + "}",
        **(extra or {}),
    }.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value


def save(nodes, inits, inputs, outputs, path, names, extra=None):
    graph = helper.make_graph(nodes, "postflight_crack_reference", inputs, outputs, inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)], producer_name="postflight")
    model.ir_version = 8
    metadata(model, names, extra)
    onnx.checker.check_model(model, full_check=True)
    onnx.save(model, path)


def mask_output():
    """The per-pixel crack score as the output `mask` (see backbone's Identity)."""
    return helper.make_tensor_value_info("mask", TensorProto.FLOAT, ["batch", 1, "height", "width"])


# The area reference model: the simulator's spalls by their colour. A
# weathered face is grey (blue nearly as strong as red); a spall's fresh
# fracture is warmer (the sand's colour), and a bar showing in it rust
# brown, warmer still. Warmth is (red - blue) over the pixel's sum, which
# light and shade do not change; vegetation (green above red) is not a
# spall however warm.
AREA_TRAIN_PX = 320  # the long side a frame runs at: spalls need centimetres
AREA_SMOOTH = 5  # pixels: warmth averaged over this square (JPEG's chroma is coarse)
SPALL_WARMTH = (0.045, 0.2)  # between these: broken concrete
REBAR_WARMTH = 0.2  # above this: a bar
AREA_GAIN = 200.0  # logits per unit of warmth past a limit
GREEN_WEIGHT = 4.0  # green above red counts against warmth, times this


def area_network(nodes, inits):
    """Nodes from `images` to `logits` [B, 3, H, W]: background, spall,
    exposed_rebar."""
    rows = lambda *w: np.array(w, dtype=np.float32).reshape(1, 3, 1, 1)
    inits += [
        const("a_sum_w", rows(1.0, 1.0, 1.0)),
        const("a_warm_w", rows(1.0, 0.0, -1.0)),
        const("a_green_w", rows(-1.0, 1.0, 0.0)),
        const("a_eps", np.array(0.02, dtype=np.float32)),
        const("a_spall_lo", np.array(SPALL_WARMTH[0], dtype=np.float32)),
        const("a_spall_hi", np.array(SPALL_WARMTH[1], dtype=np.float32)),
        const("a_rebar", np.array(REBAR_WARMTH, dtype=np.float32)),
        const("a_gain", np.array(AREA_GAIN, dtype=np.float32)),
        const("a_green", np.array(GREEN_WEIGHT, dtype=np.float32)),
    ]
    n = helper.make_node
    pad = AREA_SMOOTH // 2
    pool = dict(kernel_shape=[AREA_SMOOTH, AREA_SMOOTH], pads=[pad] * 4, count_include_pad=0)
    nodes += [
        n("Conv", ["images", "a_sum_w"], ["a_sum0"]),
        n("Add", ["a_sum0", "a_eps"], ["a_sum"]),
        n("Conv", ["images", "a_warm_w"], ["a_rb"]),
        n("Conv", ["images", "a_green_w"], ["a_gr"]),
        n("Div", ["a_rb", "a_sum"], ["a_warm_px"]),
        n("Relu", ["a_gr"], ["a_gr_pos"]),
        n("Div", ["a_gr_pos", "a_sum"], ["a_green_px"]),
        n("AveragePool", ["a_warm_px"], ["a_warm"], **pool),
        n("AveragePool", ["a_green_px"], ["a_greenness"], **pool),
        n("Mul", ["a_greenness", "a_green"], ["a_green_penalty"]),
        # Spall: warmer than the low limit and cooler than a bar.
        n("Sub", ["a_warm", "a_spall_lo"], ["a_over_lo"]),
        n("Sub", ["a_spall_hi", "a_warm"], ["a_under_hi"]),
        n("Min", ["a_over_lo", "a_under_hi"], ["a_spall_margin"]),
        n("Sub", ["a_spall_margin", "a_green_penalty"], ["a_spall_net"]),
        n("Mul", ["a_spall_net", "a_gain"], ["spall_logit"]),
        n("Sub", ["a_warm", "a_rebar"], ["a_rebar_margin"]),
        n("Sub", ["a_rebar_margin", "a_green_penalty"], ["a_rebar_net"]),
        n("Mul", ["a_rebar_net", "a_gain"], ["rebar_logit"]),
        n("Sub", ["a_warm", "a_warm"], ["background_logit"]),
        n("Concat", ["background_logit", "spall_logit", "rebar_logit"], ["logits"], axis=1),
    ]


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
    images = helper.make_tensor_value_info("images", TensorProto.FLOAT, ["batch", 3, "height", "width"])

    nodes, inits = [], []
    backbone(nodes, inits)
    nodes.append(helper.make_node("Concat", ["boxes", "score"], ["output0"], axis=1))
    output = helper.make_tensor_value_info("output0", TensorProto.FLOAT, ["batch", 5, "anchors"])
    save(nodes, inits, [images], [output, mask_output()], os.path.join(out, "crack-baked.onnx"), ["crack"])

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
    save(nodes, inits, [images, txt], [output, mask_output()], os.path.join(out, "crack-open.onnx"), ["crack"])

    nodes, inits = [], []
    backbone(nodes, inits)
    nodes += [
        # Logits whose softmax is sigmoid(line_g): (-line_g / 2, line_g / 2).
        helper.make_node("Div", ["line_g", "two"], ["crack_logit"]),
        helper.make_node("Neg", ["crack_logit"], ["background_logit"]),
        helper.make_node("Concat", ["background_logit", "crack_logit"], ["logits"], axis=1),
    ]
    logits = helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["batch", 2, "height", "width"])
    save(nodes, inits, [images], [logits], os.path.join(out, "crack-semantic.onnx"), ["crack"])

    nodes, inits = [], []
    area_network(nodes, inits)
    logits = helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["batch", 3, "height", "width"])
    save(nodes, inits, [images], [logits], os.path.join(out, "area-reference.onnx"),
         ["background", "spall", "exposed_rebar"],
         {"description": "postflight reference area-defect segmenter for simulated flights (hand-designed colour network, not trained)",
          "task": "segment", "postflight.train_px": str(AREA_TRAIN_PX)})

    with open(os.path.join(out, "prompts.json"), "w") as f:
        json.dump({name: [round(float(x), 7) for x in v] for name, v in prompt_embeddings().items()}, f)


if __name__ == "__main__":
    main()
