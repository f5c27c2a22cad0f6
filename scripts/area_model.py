#!/usr/bin/env python3
"""Train, export and score postflight's area-defect segmenter (issue 76).

The model segments concrete spalling and exposed reinforcement in a photo:
a small U-Net, trained from nothing (no pretrained weights: nothing is
downloaded) on the hand-drawn outlines of `../shared/data/spalling`
(CC BY 4.0: the model card shipped with the model credits it as the
set's README asks), on the CPU.

    area_model.py split   DATA                    which photos are held back
    area_model.py train   DATA --out DIR [--minutes M] [--epochs N]
    area_model.py export  DIR --onnx FILE
    area_model.py score   DATA --onnx FILE        the held-back photos, by ONNX Runtime

`train` checkpoints after every epoch (DIR/checkpoint.pt) and resumes from
it, so a run cut short by a session's end goes on where it stopped; its
log (DIR/log.jsonl) has each epoch's loss and the held-back photos' IoU
per class. The held-back photos are chosen by a hash of each photo's name
(its source name before Roboflow's `.rf.` suffix), VAL_SHARE of them: the
same on any machine, whatever the order of the files.

The exported graph takes `images` [B, 3, H, W], RGB on 0..1 (H and W
multiples of 16), and gives `logits` [B, 3, H, W] over background,
exposed_rebar and spalling (their softmax per pixel), the interface of
postflight's semantic crack segmenters; its metadata names the classes
(`names`, as Ultralytics writes them) and the input (ONNX's Image.*
keys), and says the scale it was trained at (`postflight.train_px`).
"""

import argparse
import hashlib
import json
import math
import os
import random
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

CLASSES = ("background", "exposed_rebar", "spalling")
# The dataset's class ids (data.yaml) -> channels of the model's output.
DATASET_CLASS = {0: 1, 1: 2}
VAL_SHARE = 0.15
# Photos are kept in memory with their longer side this long.
STORE_PX = 512
# Training crops, pixels, taken from a photo scaled so its shorter side is
# between CROP_PX and STORE_PX.
CROP_PX = 256
BATCH = 8
LR = 2e-3
WIDTHS = (16, 32, 64, 128)
SEED = 0


def source_name(path):
    """A photo's name before Roboflow's `.rf.<hash>` suffix: its copies
    share it."""
    return path.name.split(".rf.")[0]


def held_back(path):
    digest = hashlib.sha1(source_name(path).encode()).hexdigest()
    return int(digest[:8], 16) / 2**32 < VAL_SHARE


def photos(data):
    images = sorted((Path(data) / "train" / "images").glob("*.jpg"))
    if not images:
        raise SystemExit(f"area_model: no photos in {data}/train/images (the spalling set's layout)")
    return images


def label_path(image):
    return image.parent.parent / "labels" / (image.stem + ".txt")


def outlines(image):
    """Each outline of a photo: (channel, [(x, y), ...] as fractions)."""
    out = []
    path = label_path(image)
    if not path.exists():
        return out
    for line in path.read_text().splitlines():
        v = line.split()
        if len(v) < 7:
            continue
        cls, xy = int(v[0]), [float(t) for t in v[1:]]
        if cls in DATASET_CLASS:
            out.append((DATASET_CLASS[cls], list(zip(xy[0::2], xy[1::2]))))
    return out


def rasterised(image, size):
    """The photo's outlines drawn as a class map of `size` (w, h): spalling
    first, exposed rebar over it (bars lie in spalls)."""
    w, h = size
    canvas = Image.new("L", size, 0)
    draw = ImageDraw.Draw(canvas)
    for channel in (2, 1):
        for c, pts in outlines(image):
            if c == channel and len(pts) >= 3:
                draw.polygon([(x * w, y * h) for x, y in pts], fill=channel)
    return np.asarray(canvas, dtype=np.uint8)


def stored(image):
    """The photo (RGB uint8) and its class map, longer side STORE_PX."""
    img = Image.open(image).convert("RGB")
    scale = STORE_PX / max(img.size)
    size = (max(1, round(img.width * scale)), max(1, round(img.height * scale)))
    img = img.resize(size, Image.BILINEAR)
    return np.asarray(img, dtype=np.uint8), rasterised(image, size)


def split(args):
    images = photos(args.data)
    val = [p for p in images if held_back(p)]
    print(f"{len(images)} photos; held back {len(val)} ({len(val) / len(images):.0%}), trained on {len(images) - len(val)}")
    for p in val:
        print(p.name)


def model():
    import torch
    from torch import nn

    def block(cin, cout):
        return nn.Sequential(
            nn.Conv2d(cin, cout, 3, padding=1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True),
            nn.Conv2d(cout, cout, 3, padding=1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True),
        )

    class UNet(nn.Module):
        def __init__(self):
            super().__init__()
            self.down = nn.ModuleList()
            cin = 3
            for w in WIDTHS:
                self.down.append(block(cin, w))
                cin = w
            self.middle = block(WIDTHS[-1], WIDTHS[-1])
            self.up = nn.ModuleList()
            for w in reversed(WIDTHS):
                self.up.append(block(cin + w, w))
                cin = w
            self.head = nn.Conv2d(cin, len(CLASSES), 1)
            self.register_buffer("mean", torch.tensor([0.485, 0.456, 0.406]).view(1, 3, 1, 1))
            self.register_buffer("std", torch.tensor([0.229, 0.224, 0.225]).view(1, 3, 1, 1))

        def forward(self, x):
            x = (x - self.mean) / self.std
            skips = []
            for d in self.down:
                x = d(x)
                skips.append(x)
                x = nn.functional.max_pool2d(x, 2)
            x = self.middle(x)
            for u, s in zip(self.up, reversed(skips)):
                x = nn.functional.interpolate(x, scale_factor=2, mode="bilinear", align_corners=False)
                x = u(torch.cat([x, s], 1))
            return self.head(x)

    return UNet()


def crops(store, rng):
    """One training batch: random crops, scaled, flipped and turned."""
    xs, ys = [], []
    for _ in range(BATCH):
        img, lab = store[rng.randrange(len(store))]
        h, w = lab.shape
        short = rng.uniform(CROP_PX, max(CROP_PX, min(h, w)))
        scale = short / min(h, w)
        size = (max(CROP_PX, round(w * scale)), max(CROP_PX, round(h * scale)))
        im = np.asarray(Image.fromarray(img).resize(size, Image.BILINEAR))
        lb = np.asarray(Image.fromarray(lab).resize(size, Image.NEAREST))
        y0, x0 = rng.randrange(size[1] - CROP_PX + 1), rng.randrange(size[0] - CROP_PX + 1)
        im, lb = im[y0:y0 + CROP_PX, x0:x0 + CROP_PX], lb[y0:y0 + CROP_PX, x0:x0 + CROP_PX]
        k = rng.randrange(4)
        im, lb = np.rot90(im, k), np.rot90(lb, k)
        if rng.random() < 0.5:
            im, lb = im[:, ::-1], lb[:, ::-1]
        # Exposure, as photos of a flight differ.
        im = np.clip(im.astype(np.float32) * rng.uniform(0.7, 1.3), 0, 255)
        xs.append(im.transpose(2, 0, 1) / 255.0)
        ys.append(lb.copy())
    return np.stack(xs).astype(np.float32), np.stack(ys).astype(np.int64)


def loss_of(logits, target):
    """Cross-entropy plus the defect classes' soft Dice (their pixels are
    few against the background's)."""
    import torch

    ce = torch.nn.functional.cross_entropy(logits, target)
    p = logits.softmax(1)
    dice = 0.0
    for c in range(1, len(CLASSES)):
        t = (target == c).float()
        inter = (p[:, c] * t).sum()
        dice = dice + 1 - (2 * inter + 1) / (p[:, c].sum() + t.sum() + 1)
    return ce + dice / (len(CLASSES) - 1)


def padded(img):
    """An image (H, W, 3 uint8) padded to multiples of 16, as a batch of one."""
    h, w = img.shape[:2]
    ph, pw = (-h) % 16, (-w) % 16
    x = np.pad(img, ((0, ph), (0, pw), (0, 0)), mode="edge").transpose(2, 0, 1)[None] / 255.0
    return x.astype(np.float32), (h, w)


class Overlap:
    """Each defect class's predicted and drawn pixels, summed over photos:
    its IoU."""

    def __init__(self):
        self.inter = np.zeros(len(CLASSES))
        self.union = np.zeros(len(CLASSES))

    def add(self, pred, lab):
        for c in range(1, len(CLASSES)):
            self.inter[c] += np.sum((pred == c) & (lab == c))
            self.union[c] += np.sum((pred == c) | (lab == c))

    def iou(self):
        return {CLASSES[c]: float(self.inter[c] / max(self.union[c], 1)) for c in range(1, len(CLASSES))}


def iou_on(net, store):
    """IoU per defect class over the held-back photos."""
    import torch

    overlap = Overlap()
    net.eval()
    with torch.no_grad():
        for img, lab in store:
            x, (h, w) = padded(img)
            overlap.add(net(torch.from_numpy(x))[0].argmax(0).numpy()[:h, :w], lab)
    net.train()
    return overlap.iou()


def train(args):
    import torch

    torch.manual_seed(SEED)
    torch.set_num_threads(os.cpu_count() or 1)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    images = photos(args.data)
    t0 = time.time()
    train_store = [stored(p) for p in images if not held_back(p)]
    val_store = [stored(p) for p in images if held_back(p)]
    print(f"loaded {len(train_store)} training and {len(val_store)} held-back photos in {time.time() - t0:.0f} s", flush=True)
    net = model()
    steps_per_epoch = math.ceil(len(train_store) / BATCH)
    opt = torch.optim.AdamW(net.parameters(), lr=LR, weight_decay=1e-4)
    total = args.epochs * steps_per_epoch
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda s: 0.5 * (1 + math.cos(math.pi * min(s, total) / total)))
    epoch = 0
    ckpt = out / "checkpoint.pt"
    if ckpt.exists():
        state = torch.load(ckpt, weights_only=False)
        net.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        sched.load_state_dict(state["schedule"])
        epoch = state["epoch"]
        torch.set_rng_state(state["torch_rng"])
        print(f"resumed after epoch {epoch}", flush=True)
    params = sum(p.numel() for p in net.parameters())
    print(f"{params} parameters, {steps_per_epoch} steps an epoch of {BATCH}", flush=True)
    start = time.time()
    while epoch < args.epochs:
        if args.minutes and time.time() - start > args.minutes * 60:
            print(f"stopping after {args.minutes} minutes; run again to go on", flush=True)
            break
        # Each epoch's crops from its own seed: a resumed run draws what an
        # uncut one would.
        rng = random.Random(SEED * 1000 + epoch)
        t = time.time()
        losses = []
        for _ in range(steps_per_epoch):
            x, y = crops(train_store, rng)
            loss = loss_of(net(torch.from_numpy(x)), torch.from_numpy(y))
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            losses.append(float(loss.detach()))
        epoch += 1
        iou = iou_on(net, val_store)
        row = {"epoch": epoch, "loss": float(np.mean(losses)), "iou": iou, "seconds": round(time.time() - t)}
        with open(out / "log.jsonl", "a") as f:
            f.write(json.dumps(row) + "\n")
        print(json.dumps(row), flush=True)
        state = {"model": net.state_dict(), "optimizer": opt.state_dict(), "schedule": sched.state_dict(),
                 "epoch": epoch, "torch_rng": torch.get_rng_state()}
        torch.save(state, out / "checkpoint.tmp")
        os.replace(out / "checkpoint.tmp", ckpt)
    if epoch < args.epochs:
        # Not finished: nothing to export yet (the wrapper stops here).
        raise SystemExit(3)


def export(args):
    import onnx
    import torch

    state = torch.load(Path(args.dir) / "checkpoint.pt", weights_only=False)
    net = model()
    net.load_state_dict(state["model"])
    net.eval()
    x = torch.zeros(1, 3, CROP_PX, CROP_PX)
    torch.onnx.export(net, x, args.onnx, input_names=["images"], output_names=["logits"],
                      dynamic_axes={"images": {0: "batch", 2: "height", 3: "width"},
                                    "logits": {0: "batch", 2: "height", 3: "width"}},
                      opset_version=17, dynamo=False)
    m = onnx.load(args.onnx)
    meta = {
        "names": "{" + ", ".join(f"{i}: '{n}'" for i, n in enumerate(CLASSES)) + "}",
        "Image.BitmapPixelFormat": "Rgb8",
        "Image.NominalPixelRange": "Normalized_0_1",
        "stride": "16",
        "postflight.train_px": str(STORE_PX),
        "postflight.epochs": str(state["epoch"]),
    }
    for k, v in meta.items():
        p = m.metadata_props.add()
        p.key, p.value = k, v
    onnx.save(m, args.onnx)
    print(f"wrote {args.onnx} ({os.path.getsize(args.onnx) / 1e6:.1f} MB) after epoch {state['epoch']}")


# Predicted regions smaller than this (pixels at STORE_PX) are specks, not
# instances.
MIN_INSTANCE_PX = 64
MATCH_IOU = 0.5


def instances(image, size, channel):
    """Each hand-drawn outline of `channel` as its own mask of `size`."""
    w, h = size
    out = []
    for c, pts in outlines(image):
        if c == channel and len(pts) >= 3:
            canvas = Image.new("L", size, 0)
            ImageDraw.Draw(canvas).polygon([(x * w, y * h) for x, y in pts], fill=1)
            out.append(np.asarray(canvas, dtype=bool))
    return out


def matched(truths, preds):
    """Pairs of truth and predicted instances at IoU MATCH_IOU or more, one
    to one, the best pairs first."""
    pairs = []
    for i, t in enumerate(truths):
        for j, p in enumerate(preds):
            inter = np.sum(t & p)
            if inter:
                pairs.append((inter / np.sum(t | p), i, j))
    used_t, used_p, n = set(), set(), 0
    for iou, i, j in sorted(pairs, reverse=True):
        if iou >= MATCH_IOU and i not in used_t and j not in used_p:
            used_t.add(i)
            used_p.add(j)
            n += 1
    return n


def score(args):
    """IoU per class (pixels summed over the held-back photos) and instance
    precision and recall at IoU MATCH_IOU (predicted instances: connected
    regions of MIN_INSTANCE_PX or more), the model run by ONNX Runtime."""
    import onnxruntime as ort
    from scipy import ndimage

    session = ort.InferenceSession(args.onnx, providers=["CPUExecutionProvider"])
    held = [p for p in photos(args.data) if held_back(p)]
    overlap = Overlap()
    counts = {c: [0, 0, 0] for c in range(1, len(CLASSES))}  # matched, truths, predictions
    for path in held:
        img, lab = stored(path)
        x, (h, w) = padded(img)
        pred = session.run(None, {"images": x})[0][0].argmax(0)[:h, :w]
        overlap.add(pred, lab)
        for c in range(1, len(CLASSES)):
            regions, n = ndimage.label(pred == c, structure=np.ones((3, 3)))
            preds = [regions == k for k in range(1, n + 1) if np.sum(regions == k) >= MIN_INSTANCE_PX]
            truths = instances(path, (w, h), c)
            counts[c][0] += matched(truths, preds)
            counts[c][1] += len(truths)
            counts[c][2] += len(preds)
    print(f"{len(held)} held-back photos, {args.onnx}")
    print("| class | IoU | instances (hand-drawn) | predicted | precision at IoU 0.5 | recall at IoU 0.5 |")
    print("|---|---|---|---|---|---|")
    iou = overlap.iou()
    for c in range(1, len(CLASSES)):
        m, t, p = counts[c]
        print(f"| {CLASSES[c]} | {iou[CLASSES[c]]:.3f} | {t} | {p} | {m / max(p, 1):.2f} | {m / max(t, 1):.2f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", required=True)
    s = sub.add_parser("split")
    s.add_argument("data")
    t = sub.add_parser("train")
    t.add_argument("data")
    t.add_argument("--out", required=True)
    t.add_argument("--epochs", type=int, default=60)
    t.add_argument("--minutes", type=float, default=0.0, help="stop after the epoch that passes this (0: never)")
    e = sub.add_parser("export")
    e.add_argument("dir")
    e.add_argument("--onnx", required=True)
    c = sub.add_parser("score")
    c.add_argument("data")
    c.add_argument("--onnx", required=True)
    args = ap.parse_args()
    {"split": split, "train": train, "export": export, "score": score}[args.command](args)


if __name__ == "__main__":
    main()
