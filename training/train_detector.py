#!/usr/bin/python3
"""Trains moslam's YOLO-style single-stage detector on a YOLO-layout dataset, exports ONNX.

Dataset layout (what `moslam render --format yolo` writes):
    DIR/classes.txt, DIR/images/NAME.png, DIR/labels/NAME.txt (`class cx cy w h`, fractions)

Network: a small convolutional backbone down to stride 16, a top-down (deconvolution) path back
to stride 8, and one head at stride 8: for every cell of the W/8 x H/8 grid one box (centre
offset from the cell corner in cell units, width/height as fractions of the input), an objectness and class
probabilities. The exported ONNX output "grid" is [1, 5 + C, H/8, W/8], already activated: the
"moslam" format of src/moslam/detection/detector.h. Images are stretched to the input size,
RGB, scaled to [0, 1] (what the C++ Detector feeds).

Run with Debian's python (python3-torch, python3-onnx; scripts/setup-training.sh), e.g.
    timeout 2400 /usr/bin/python3 training/train_detector.py --train data/det_train \
        --val data/det_val --out models/detector/moslam_yolo.onnx --minutes 20 --seed 1
CPU only, one thread (faster than two on a shared two-core machine).
"""
import argparse
import json
import os
import subprocess
import sys
import time
import traceback


def _die(exc_type, exc, tb):
    # Debian's torch 1.13 can hang at exit after an uncaught exception: exit hard.
    traceback.print_exception(exc_type, exc, tb)
    sys.stderr.flush()
    os._exit(1)


sys.excepthook = _die

import numpy as np  # noqa: E402
import torch  # noqa: E402
import torch.nn as nn  # noqa: E402
import torch.nn.functional as F  # noqa: E402
from PIL import Image  # noqa: E402

STRIDE = 8


# ----------------------------------------------------------------------------- data
def read_dataset(root, width, height):
    """Images as a uint8 tensor [N, 3, H, W] (RGB, stretched), labels as float arrays [k, 5]."""
    with open(os.path.join(root, "classes.txt")) as f:
        classes = [line.strip() for line in f if line.strip()]
    names = sorted(n for n in os.listdir(os.path.join(root, "images"))
                   if n.lower().endswith((".png", ".jpg", ".jpeg", ".bmp")))
    if not names:
        raise SystemExit(f"{root}/images holds no image")
    images = torch.empty((len(names), 3, height, width), dtype=torch.uint8)
    labels = []
    for i, name in enumerate(names):
        img = Image.open(os.path.join(root, "images", name)).convert("RGB")
        if img.size != (width, height):
            img = img.resize((width, height), Image.BILINEAR)
        images[i] = torch.from_numpy(np.asarray(img, dtype=np.uint8).copy()).permute(2, 0, 1)
        path = os.path.join(root, "labels", os.path.splitext(name)[0] + ".txt")
        rows = []
        if os.path.exists(path):
            with open(path) as f:
                for line_no, line in enumerate(f, 1):
                    if not line.strip():
                        continue
                    v = line.split()
                    if len(v) != 5:
                        raise SystemExit(f"{path}:{line_no}: expected 'class cx cy w h'")
                    rows.append([float(x) for x in v])
        labels.append(np.array(rows, np.float32).reshape(-1, 5))
    return classes, names, images, labels


def augment(images, labels, rng, crop_keep):
    """Flip, mild zoom-in crop, colour jitter. images float [B, 3, H, W] in [0, 1]. A crop keeps
    a label when more than crop_keep of its box's area stays inside; the others become background
    (the renderer's labelling rule skips objects with less than half of their projected extent
    inside the image: YoloLabelConfig::min_in_image_fraction)."""
    b, _, h, w = images.shape
    out_labels = []
    for i in range(b):
        lab = labels[i].copy()
        if rng.random() < 0.5:
            images[i] = images[i].flip(-1)
            lab[:, 1] = 1.0 - lab[:, 1]
        if rng.random() < 0.4:
            s = rng.uniform(0.75, 1.0)
            cw, ch = s, s
            x0, y0 = rng.uniform(0, 1 - cw), rng.uniform(0, 1 - ch)
            px0, py0 = int(round(x0 * w)), int(round(y0 * h))
            pw, ph = max(8, int(round(cw * w))), max(8, int(round(ch * h)))
            crop = images[i:i + 1, :, py0:py0 + ph, px0:px0 + pw]
            images[i] = F.interpolate(crop, size=(h, w), mode="bilinear", align_corners=False)[0]
            x0, y0, cw, ch = px0 / w, py0 / h, pw / w, ph / h
            if len(lab):
                x1 = np.clip(lab[:, 1] - lab[:, 3] / 2, x0, x0 + cw)
                x2 = np.clip(lab[:, 1] + lab[:, 3] / 2, x0, x0 + cw)
                y1 = np.clip(lab[:, 2] - lab[:, 4] / 2, y0, y0 + ch)
                y2 = np.clip(lab[:, 2] + lab[:, 4] / 2, y0, y0 + ch)
                kept = ((x2 - x1) * (y2 - y1)) / np.maximum(lab[:, 3] * lab[:, 4], 1e-9)
                nl = np.stack([lab[:, 0], ((x1 + x2) / 2 - x0) / cw, ((y1 + y2) / 2 - y0) / ch,
                               (x2 - x1) / cw, (y2 - y1) / ch], 1)
                lab = nl[kept > crop_keep].astype(np.float32)
        out_labels.append(lab)
    # Colour jitter: brightness, contrast, saturation per image.
    bright = torch.from_numpy(rng.uniform(0.7, 1.3, (b, 1, 1, 1)).astype(np.float32))
    contrast = torch.from_numpy(rng.uniform(0.7, 1.3, (b, 1, 1, 1)).astype(np.float32))
    sat = torch.from_numpy(rng.uniform(0.6, 1.4, (b, 1, 1, 1)).astype(np.float32))
    images = images * bright
    mean = images.mean(dim=(1, 2, 3), keepdim=True)
    images = (images - mean) * contrast + mean
    grey = images.mean(dim=1, keepdim=True)
    images = (images - grey) * sat + grey
    images = images + torch.from_numpy(rng.normal(0, 0.01, images.shape).astype(np.float32))
    return images.clamp_(0, 1), out_labels


def build_targets(labels, gh, gw, num_classes):
    """Per cell: mask, x/y offsets, sqrt(w), sqrt(h), class. As in YOLOv5, an object is owned by
    the cell holding its centre and by the two neighbours nearest to the centre (one in x, one
    in y), whose offsets then lie in [-0.5, 1.5]; where objects compete, the smaller wins."""
    b = len(labels)
    mask = torch.zeros((b, gh, gw), dtype=torch.bool)
    box = torch.zeros((b, 4, gh, gw))
    cls = torch.zeros((b, gh, gw), dtype=torch.long)
    for i, lab in enumerate(labels):
        if not len(lab):
            continue
        order = np.argsort(-lab[:, 3] * lab[:, 4])  # large first, small overwrites
        for c, cx, cy, w, h in lab[order]:
            x, y = cx * gw, cy * gh
            gx, gy = min(int(x), gw - 1), min(int(y), gh - 1)
            nx = gx - 1 if x - gx < 0.5 else gx + 1
            ny = gy - 1 if y - gy < 0.5 else gy + 1
            for ox, oy in ((gx, gy), (nx, gy), (gx, ny)):
                if 0 <= ox < gw and 0 <= oy < gh:
                    mask[i, oy, ox] = True
                    box[i, :, oy, ox] = torch.tensor([x - ox, y - oy, np.sqrt(w), np.sqrt(h)])
                    cls[i, oy, ox] = int(c)
    return mask, box, cls


# ----------------------------------------------------------------------------- model
def cbr(cin, cout, stride=1, dilation=1):
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, stride, dilation, dilation=dilation, bias=False),
        nn.BatchNorm2d(cout), nn.LeakyReLU(0.1, inplace=True))


class Net(nn.Module):
    """Backbone to stride 16, deconvolution back to stride 8, one head at stride 8."""

    def __init__(self, num_classes, width=1.0):
        super().__init__()
        c = [max(8, int(round(x * width))) for x in (16, 32, 64, 128)]
        self.c3 = nn.Sequential(cbr(3, c[0], 2), cbr(c[0], c[1], 2), cbr(c[1], c[1]),
                                cbr(c[1], c[2], 2), cbr(c[2], c[2]))
        self.c4 = nn.Sequential(cbr(c[2], c[3], 2), cbr(c[3], c[3]), cbr(c[3], c[3], dilation=2),
                                cbr(c[3], c[3], dilation=4))
        self.up = nn.Sequential(nn.ConvTranspose2d(c[3], c[2], 2, 2, bias=False),
                                nn.BatchNorm2d(c[2]), nn.LeakyReLU(0.1, inplace=True))
        self.p3 = nn.Sequential(cbr(2 * c[2], c[2]), cbr(c[2], c[2]))
        # Separate 1x1 heads so the export needs no Slice.
        self.xy = nn.Conv2d(c[2], 2, 1)
        self.wh = nn.Conv2d(c[2], 2, 1)
        self.obj = nn.Conv2d(c[2], 1, 1)
        self.cls = nn.Conv2d(c[2], num_classes, 1)
        nn.init.constant_(self.obj.bias, -4.0)  # start with low objectness

    def forward(self, x):
        f3 = self.c3(x)
        f4 = self.c4(f3)
        p = self.p3(torch.cat([f3, self.up(f4)], 1))
        return self.xy(p), self.wh(p), self.obj(p), self.cls(p)


class Exported(nn.Module):
    """Activated output [1, 5 + C, Gh, Gw]: x, y offsets (cell units from the cell's corner, in
    [-0.5, 1.5]), w, h fractions of the input, objectness, class probabilities."""

    def __init__(self, net):
        super().__init__()
        self.net = net

    def forward(self, x):
        xy, wh, obj, cls = self.net(x)
        s = torch.sigmoid(wh)
        return torch.cat([2.0 * torch.sigmoid(xy) - 0.5, s * s, torch.sigmoid(obj),
                          torch.softmax(cls, 1)], 1)


def loss_fn(outputs, mask, box, cls):
    xy, wh, obj, logits = outputs
    b = xy.shape[0]
    pos = mask.float()
    n_pos = max(1.0, float(pos.sum()))
    l_obj = F.binary_cross_entropy_with_logits(obj[:, 0], pos, reduction="sum") / b
    m = mask.unsqueeze(1)
    l_xy = (torch.abs(2.0 * torch.sigmoid(xy) - 0.5 - box[:, 0:2]) * m).sum() / n_pos
    l_wh = (torch.abs(torch.sigmoid(wh) - box[:, 2:4]) * m).sum() / n_pos
    l_cls = F.cross_entropy(logits.permute(0, 2, 3, 1)[mask], cls[mask], reduction="sum") / n_pos
    return l_obj + 5.0 * (l_xy + l_wh) + l_cls, dict(obj=float(l_obj), xy=float(l_xy),
                                                      wh=float(l_wh), cls=float(l_cls))


# ----------------------------------------------------------------------------- evaluation
def decode(grid, width, height, threshold, nms_iou):
    """The C++ Detector's decoding (moslam format, per-class NMS) on one activated grid
    [5 + C, Gh, Gw]; boxes in network input pixels: [(class, score, x, y, w, h)]."""
    g = grid.numpy()
    c5, gh, gw = g.shape
    gy, gx = np.mgrid[0:gh, 0:gw]
    cls = g[5:].argmax(0)
    score = g[4] * g[5:].max(0)
    keep = score >= threshold
    cx = (gx + g[0]) * width / gw
    cy = (gy + g[1]) * height / gh
    w, h = g[2] * width, g[3] * height
    cand = [(int(cls[k]), float(score[k]), float(cx[k] - w[k] / 2), float(cy[k] - h[k] / 2),
             float(w[k]), float(h[k])) for k in zip(*np.nonzero(keep))]
    cand.sort(key=lambda d: -d[1])
    out = []
    for d in cand:
        if all(o[0] != d[0] or iou(o[2:], d[2:]) <= nms_iou for o in out):
            out.append(d)
    return out


def iou(a, b):
    ix = max(0.0, min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


def evaluate(model, images, labels, num_classes, width, height, threshold=0.3, batch=32):
    """Precision / recall at the threshold and mAP@0.5 (all-point AP), as the C++ evaluator."""
    model.eval()
    scored = [[] for _ in range(num_classes)]
    n_gt = [0] * num_classes
    tp_at = fp_at = 0
    with torch.no_grad():
        for s in range(0, len(images), batch):
            grids = Exported(model)(images[s:s + batch].float() / 255.0)
            for j in range(grids.shape[0]):
                dets = decode(grids[j], width, height, 0.01, 0.45)
                lab = labels[s + j]
                gts = [(int(c), (cx - w / 2) * width, (cy - h / 2) * height, w * width,
                        h * height) for c, cx, cy, w, h in lab]
                for g in gts:
                    n_gt[g[0]] += 1
                taken = [False] * len(gts)
                for d in dets:
                    best, best_iou = -1, 0.0
                    for k, g in enumerate(gts):
                        if taken[k] or g[0] != d[0]:
                            continue
                        v = iou(d[2:], g[1:])
                        if v > best_iou:
                            best, best_iou = k, v
                    tp = bool(best >= 0 and best_iou >= 0.5)
                    if tp:
                        taken[best] = True
                    scored[d[0]].append((d[1], tp))
                    if d[1] >= threshold:
                        tp_at += int(tp)
                        fp_at += int(not tp)
    aps = []
    for c in range(num_classes):
        if n_gt[c] == 0:
            continue
        s = sorted(scored[c], key=lambda x: -x[0])
        tps = np.cumsum([t for _, t in s]) if s else np.zeros(0)
        rec = np.concatenate([[0], tps / n_gt[c], [tps[-1] / n_gt[c] if len(s) else 0]])
        prec = np.concatenate([[0], tps / np.arange(1, len(s) + 1), [0]])
        for k in range(len(prec) - 2, -1, -1):
            prec[k] = max(prec[k], prec[k + 1])
        aps.append(float(np.sum((rec[1:] - rec[:-1]) * prec[1:])))
    model.train()
    total_gt = sum(n_gt)
    return dict(precision=tp_at / max(1, tp_at + fp_at), recall=tp_at / max(1, total_gt),
                map50=float(np.mean(aps)) if aps else 0.0, tp=tp_at, fp=fp_at, gt=total_gt)


# ----------------------------------------------------------------------------- export
def strip_identity(path):
    """OpenCV 4.6 rejects ONNX Identity nodes (torch 1.13 emits them for shared initializers):
    rewire their consumers to the Identity input and drop them."""
    import onnx
    model = onnx.load(path)
    g = model.graph
    graph_outputs = {o.name for o in g.output}
    rename = {}
    kept = []
    for node in g.node:
        if node.op_type == "Identity" and node.output[0] not in graph_outputs:
            rename[node.output[0]] = node.input[0]
        else:
            kept.append(node)
    for node in kept:
        for k, name in enumerate(node.input):
            while name in rename:
                name = rename[name]
            node.input[k] = name
    del g.node[:]
    g.node.extend(kept)
    onnx.checker.check_model(model)
    onnx.save(model, path)
    return len(rename)


def export(model, num_classes, width, height, path, opset):
    model.eval()
    wrapper = Exported(model)
    dummy = torch.zeros(1, 3, height, width)
    torch.onnx.export(wrapper, dummy, path, opset_version=opset, input_names=["images"],
                      output_names=["grid"], do_constant_folding=True)
    removed = strip_identity(path)
    return removed


def init_from_onnx(model, path):
    """Loads an exported model (this script's ONNX, the same --width) into `model`. The export
    folds each conv + batch norm into one conv with a bias: the conv takes the folded weight, its
    batch norm becomes the bias alone (weight 1, running mean 0, running variance 1 - eps), so the
    network computes the exported function as long as its batch norms stay in eval mode (the
    caller freezes them: the batch statistics they were trained with are not in the file)."""
    import onnx
    from onnx import numpy_helper
    graph = onnx.load(path).graph
    tensors = {t.name: torch.from_numpy(numpy_helper.to_array(t).copy()) for t in graph.initializer}
    state = model.state_dict()
    named = 0
    for name, t in tensors.items():
        key = name[len("net."):] if name.startswith("net.") else None
        if key in state:
            if state[key].shape != t.shape:
                raise SystemExit(f"--init-onnx: {name} has shape {list(t.shape)}, the model "
                                 f"{list(state[key].shape)} (another --width?)")
            state[key] = t
            named += 1
    by_name = {f"net.{k}" for k in state}
    folded = [(n.input[1], n.input[2]) for n in graph.node
              if n.op_type == "Conv" and len(n.input) == 3 and n.input[1] not in by_name]
    pairs = [m for m in model.modules() if isinstance(m, nn.Sequential) and len(m) == 3 and
             isinstance(m[0], nn.Conv2d) and isinstance(m[1], nn.BatchNorm2d)]
    if len(folded) != len(pairs):
        raise SystemExit(f"--init-onnx: {len(folded)} folded convolutions in {path}, the model "
                         f"has {len(pairs)} conv + batch norm blocks")
    prefix = {id(m): k for k, m in model.named_modules()}
    for (w, b), block in zip(folded, pairs):
        k = prefix[id(block)]
        if state[f"{k}.0.weight"].shape != tensors[w].shape:
            raise SystemExit(f"--init-onnx: {w} has shape {list(tensors[w].shape)}, {k}.0 "
                             f"{list(state[k + '.0.weight'].shape)}")
        eps = block[1].eps
        state[f"{k}.0.weight"] = tensors[w]
        state[f"{k}.1.weight"] = torch.ones_like(state[f"{k}.1.weight"])
        state[f"{k}.1.bias"] = tensors[b]
        state[f"{k}.1.running_mean"] = torch.zeros_like(state[f"{k}.1.running_mean"])
        state[f"{k}.1.running_var"] = torch.full_like(state[f"{k}.1.running_var"], 1.0 - eps)
    model.load_state_dict(state)
    return named, len(folded)


def freeze_batch_norms(model):
    for m in model.modules():
        if isinstance(m, nn.BatchNorm2d):
            m.eval()


def check_with_opencv(moslam, model_path, classes_path, image_path, model, width, height):
    """Runs `moslam detect --image` (OpenCV DNN, one pass: the flip test off, as torch here; per-class
    NMS at 0.45, as decode() here) and compares with torch's detections."""
    cmd = [moslam, "detect", "--model", model_path, "--classes", classes_path, "--image",
           image_path, "--input-size", f"{width}x{height}", "--threshold", "0.05",
           "--no-flip-test", "--per-class-nms", "--nms", "0.45", "--json"]
    res = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    img = Image.open(image_path).convert("RGB")
    sx, sy = img.size[0] / width, img.size[1] / height
    if img.size != (width, height):
        img = img.resize((width, height), Image.BILINEAR)
    x = torch.from_numpy(np.asarray(img, np.float32) / 255.0).permute(2, 0, 1)[None]
    model.eval()
    with torch.no_grad():
        ref = decode(Exported(model)(x)[0], width, height, 0.05, 0.45)
    # The C++ Detector clips boxes to the image.
    clipped = []
    for c, sc, bx, by, bw, bh in ref:
        x0, y0 = max(0.0, bx), max(0.0, by)
        x1, y1 = min(float(width), bx + bw), min(float(height), by + bh)
        clipped.append((c, sc, x0, y0, x1 - x0, y1 - y0))
    ref = clipped
    cv_dets = res["detections"]
    worst = 0.0
    if len(cv_dets) != len(ref):
        return dict(ok=False, torch=len(ref), opencv=len(cv_dets), max_abs_diff=None)
    for d, r in zip(cv_dets, ref):
        vals = [d["confidence"], d["box"][0] / sx, d["box"][1] / sy, d["box"][2] / sx,
                d["box"][3] / sy]
        worst = max(worst, *(abs(a - b) for a, b in zip(vals, r[1:])))
        if d["class_id"] != r[0]:
            return dict(ok=False, reason="class differs")
    return dict(ok=worst < 1e-3, detections=len(ref), max_abs_diff=worst)


# ----------------------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--train", required=True, help="training dataset folder (YOLO layout)")
    ap.add_argument("--val", help="held-out dataset folder, evaluated at the end")
    ap.add_argument("--out", required=True, help="output .onnx path")
    ap.add_argument("--input-size", default="320x240", help="network input WxH, multiples of 16")
    ap.add_argument("--minutes", type=float, default=20.0, help="training time budget")
    ap.add_argument("--max-steps", type=int, default=0, help="stop after this many steps (0: time)")
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--lr", type=float, default=4e-3)
    ap.add_argument("--width", type=float, default=1.0, help="channel width multiplier")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--crop-keep", type=float, default=0.4,
                    help="a zoom crop keeps a label with more than this share of its box inside "
                    "(0.4: the shipped model's; 0.5 is the labelling rule's share of the object "
                    "inside the image: tried, models/detector/README.md)")
    ap.add_argument("--opset", type=int, default=12)
    ap.add_argument("--moslam", help="moslam binary: check OpenCV DNN against torch after export")
    ap.add_argument("--report", help="write the training summary (JSON) here")
    ap.add_argument("--save-weights", help="also save the torch state_dict here")
    ap.add_argument("--init-weights", help="start from this state_dict (--save-weights of an "
                    "earlier run with the same --width): a warm restart of the schedule")
    ap.add_argument("--init-onnx", help="start from this exported model (this script's ONNX, the "
                    "same --width), batch norms frozen (their statistics are folded in the file)")
    args = ap.parse_args()
    if args.init_weights and args.init_onnx:
        raise SystemExit("--init-weights and --init-onnx exclude each other")
    if not 0.0 <= args.crop_keep < 1.0:
        raise SystemExit("--crop-keep must be in [0, 1)")

    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    width, height = (int(v) for v in args.input_size.lower().split("x"))
    if width % 16 or height % 16:
        raise SystemExit("--input-size must be multiples of 16")

    t0 = time.time()
    classes, _, images, labels = read_dataset(args.train, width, height)
    nc = len(classes)
    val = None
    if args.val:
        vclasses, vnames, vimages, vlabels = read_dataset(args.val, width, height)
        if vclasses != classes:
            raise SystemExit("train and val classes.txt differ")
        val = (vnames, vimages, vlabels)
    print(f"loaded {len(images)} training images, {nc} classes {classes} in "
          f"{time.time() - t0:.1f} s", flush=True)

    model = Net(nc, args.width)
    if args.init_weights:
        model.load_state_dict(torch.load(args.init_weights))
        print(f"initialised from {args.init_weights}", flush=True)
    if args.init_onnx:
        named, folded = init_from_onnx(model, args.init_onnx)
        print(f"initialised from {args.init_onnx}: {named} tensors by name, {folded} folded "
              "convolutions; batch norms frozen", flush=True)
        if args.moslam and val is not None:
            image = os.path.join(args.val, "images", val[0][0])
            classes_path = os.path.join(os.path.dirname(os.path.abspath(args.init_onnx)),
                                        "classes.txt")
            same = check_with_opencv(args.moslam, args.init_onnx, classes_path, image, model,
                                     width, height)
            print("initial model against the file (OpenCV DNN):", same, flush=True)
            if not same.get("ok"):
                raise SystemExit("--init-onnx: the initialised model differs from the file")
    params = sum(p.numel() for p in model.parameters())
    print(f"model: {params} parameters, grid {width // STRIDE}x{height // STRIDE}", flush=True)
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=5e-4)
    budget = args.minutes * 60.0
    gh, gw = height // STRIDE, width // STRIDE

    t_start = time.time()
    step = 0
    ema = None
    model.train()
    if args.init_onnx:
        freeze_batch_norms(model)
    while True:
        elapsed = time.time() - t_start
        if (args.max_steps and step >= args.max_steps) or (not args.max_steps and elapsed >= budget):
            break
        frac = step / args.max_steps if args.max_steps else elapsed / budget
        warm = min(1.0, (step + 1) / 100.0)
        lr = args.lr * warm * 0.5 * (1.0 + np.cos(np.pi * min(1.0, frac)))
        for group in opt.param_groups:
            group["lr"] = lr
        idx = rng.choice(len(images), size=args.batch, replace=len(images) < args.batch)
        x = images[idx].float() / 255.0
        x, lab = augment(x, [labels[i] for i in idx], rng, args.crop_keep)
        mask, box, cls = build_targets(lab, gh, gw, nc)
        loss, parts = loss_fn(model(x), mask, box, cls)
        opt.zero_grad()
        loss.backward()
        opt.step()
        ema = float(loss) if ema is None else 0.98 * ema + 0.02 * float(loss)
        step += 1
        if step % 50 == 0:
            print(f"step {step} {elapsed:.0f}s lr {lr:.2e} loss {ema:.3f} " +
                  " ".join(f"{k} {v:.3f}" for k, v in parts.items()), flush=True)
    train_seconds = time.time() - t_start
    print(f"trained {step} steps in {train_seconds:.0f} s", flush=True)

    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    removed = export(model, nc, width, height, args.out, args.opset)
    if args.save_weights:
        torch.save(model.state_dict(), args.save_weights)
    classes_path = os.path.join(os.path.dirname(os.path.abspath(args.out)), "classes.txt")
    with open(classes_path, "w") as f:
        f.write("\n".join(classes) + "\n")
    summary = dict(train=args.train, val=args.val, init_weights=args.init_weights,
                   init_onnx=args.init_onnx, lr=args.lr, crop_keep=args.crop_keep,
                   images=len(images), classes=classes,
                   input_size=[width, height], parameters=params, steps=step, batch=args.batch,
                   seed=args.seed, train_seconds=round(train_seconds, 1),
                   onnx_bytes=os.path.getsize(args.out), identity_nodes_removed=removed)
    if val is not None:
        summary["val_torch"] = evaluate(model, val[1], val[2], nc, width, height)
        print("held-out (torch):", summary["val_torch"], flush=True)
        if args.moslam:
            image = os.path.join(args.val, "images", val[0][0])
            summary["opencv_check"] = check_with_opencv(args.moslam, args.out, classes_path,
                                                        image, model, width, height)
            print("OpenCV DNN vs torch:", summary["opencv_check"], flush=True)
    if args.report:
        with open(args.report, "w") as f:
            json.dump(summary, f, indent=2)
    print(json.dumps(summary), flush=True)
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
