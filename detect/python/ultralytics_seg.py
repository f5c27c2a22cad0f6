#!/usr/bin/env python3
"""postflight's decoding of Ultralytics instance segmentation checked against
Ultralytics itself. Needs `ultralytics` (which brings torch): run it from a
throwaway virtualenv, as scripts/check-ultralytics-seg does, never from the
project's.

    ultralytics_seg.py make OUT_DIR
        A YOLO11n-seg with random weights and one class ("crack"), exported
        to OUT_DIR/yolo11n-seg.onnx as Ultralytics exports it (no trained
        crack weights can be had here).
    ultralytics_seg.py compare FLIGHT_DIR RUN_DIR MODEL CONF IOU
        Every frame of the simulated flight through Ultralytics' own
        `predict(..., retina_masks=True)`, each instance matched to
        postflight's detection in RUN_DIR/detections.coco.json by box, and
        the two masks compared (IoU); prints a JSON summary.
"""

import io
import json
import sys

import numpy as np


def make(out):
    import onnx
    import torch
    import ultralytics
    from onnx import helper, numpy_helper
    from ultralytics import YOLO

    # The model's config with one class.
    config = f"{out}/yolo11n-seg.yaml"
    with open(f"{ultralytics.__path__[0]}/cfg/models/11/yolo11-seg.yaml") as f:
        text = f.read().replace("nc: 80", "nc: 1")
    with open(config, "w") as f:
        f.write(text)
    torch.manual_seed(0)
    model = YOLO(config, task="segment")
    model.model.names = {0: "crack"}
    head = model.model.model[-1]
    # Untrained, every anchor scores the head's bias and every mask is
    # flat: scale the class logits and the prototypes up until scores
    # spread and masks take shapes. Boxes keep their initial regression.
    with torch.no_grad():
        for branch in head.cv3:
            branch[-1].weight.mul_(300.0)
            branch[-1].bias.fill_(0.0)
        head.proto.cv3.conv.weight.mul_(100.0)
    path = model.export(format="onnx", imgsz=640, dynamic=False, simplify=False, opset=17)

    # Flat frames still give many anchors one score, and which of two tied
    # boxes NMS keeps is arbitrary: a distinct small offset per anchor on
    # the class score, in the graph so both decoders see it, breaks ties.
    graph_model = onnx.load(path)
    graph = graph_model.graph
    rows, anchors = 37, 8400
    for node in graph.node:
        node.output[:] = ["output0_raw" if o == "output0" else o for o in node.output]
    jitter = np.zeros((1, rows, anchors), dtype=np.float32)
    jitter[0, 4] = np.random.default_rng(0).permutation(anchors).astype(np.float32) * (0.02 / anchors)
    graph.initializer.append(numpy_helper.from_array(jitter, "score_jitter"))
    graph.node.append(helper.make_node("Add", ["output0_raw", "score_jitter"], ["output0"]))
    onnx.save(graph_model, path)
    print(path)


def box_iou(a, b):
    x0, y0 = max(a[0], b[0]), max(a[1], b[1])
    x1, y1 = min(a[2], b[2]), min(a[3], b[3])
    inter = max(0.0, x1 - x0) * max(0.0, y1 - y0)
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def compare(flight, run, model, conf, iou):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from PIL import Image
    from pycocotools import mask as cmask
    from ultralytics import YOLO

    coco = json.load(open(f"{run}/detections.coco.json"))
    ours_by_image = {}
    for a in coco["annotations"]:
        x, y, w, h = a["bbox"]
        ours_by_image.setdefault(a["image_id"], []).append(([x, y, x + w, y + h], a.get("segmentation")))
    image_of_stamp = {im["time_ns"]: im["id"] for im in coco["images"]}
    yolo = YOLO(model, task="segment")
    ious, theirs_total, unmatched, frames = [], 0, 0, 0
    with open(f"{flight}/flight.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for _, _, _, msg in reader.iter_decoded_messages(topics=["/camera/image_raw/compressed"]):
            stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            image_id = image_of_stamp.get(stamp)
            if image_id is None:
                continue
            frames += 1
            rgb = np.array(Image.open(io.BytesIO(bytes(msg.data))).convert("RGB"))
            r = yolo.predict(rgb[:, :, ::-1].copy(), conf=conf, iou=iou, retina_masks=True, verbose=False, max_det=100000)[0]
            theirs = []
            if r.masks is not None:
                for box, m in zip(r.boxes.xyxy.cpu().numpy(), r.masks.data.cpu().numpy()):
                    theirs.append((box.tolist(), cmask.encode(np.asfortranarray(m.astype(np.uint8)))))
            theirs_total += len(theirs)
            ours = ours_by_image.get(image_id, [])
            used = set()
            for box, rle in theirs:
                candidates = [(box_iou(box, b), k) for k, (b, _) in enumerate(ours) if k not in used]
                best_iou, best = max(candidates, default=(0.0, None))
                if best is None or best_iou < 0.9:
                    unmatched += 1
                    continue
                used.add(best)
                seg = ours[best][1]
                ious.append(0.0 if seg is None else float(cmask.iou([seg], [rle], [0])[0][0]))
    ious = np.array(ious)
    stat = lambda f: float(f(ious)) if len(ious) else None
    print(json.dumps({
        "frames": frames,
        "ultralytics_instances": theirs_total,
        "postflight_instances": sum(len(v) for v in ours_by_image.values()),
        "matched": int(len(ious)),
        "unmatched": unmatched,
        "mask_iou_median": stat(np.median),
        "mask_iou_p10": stat(lambda v: np.percentile(v, 10)),
        "mask_iou_min": stat(np.min),
        "share_iou_at_least_0_95": stat(lambda v: (v >= 0.95).mean()),
    }, indent=1))


if __name__ == "__main__":
    if sys.argv[1:2] == ["make"] and len(sys.argv) == 3:
        make(sys.argv[2])
    elif sys.argv[1:2] == ["compare"] and len(sys.argv) == 7:
        compare(sys.argv[2], sys.argv[3], sys.argv[4], float(sys.argv[5]), float(sys.argv[6]))
    else:
        sys.exit(__doc__)
