#!/usr/bin/python3
"""Writes the tiny, fixed ONNX models of detection_test (deterministic, a few hundred bytes).

Both take an 8x8 RGB input [1, 3, 8, 8] (values in [0, 1]) and have 2 classes.

tiny_moslam.onnx  output "grid" [1, 7, 2, 2] in the moslam grid format (detector.h):
    Conv(input, W, k=4, s=4) + K. W is zero except for the objectness channel (4), which
    averages its 4x4x3 patch: the objectness of a cell = mean intensity of its quarter of the
    input. K (below) gives each cell's box offsets, size and class probabilities.
tiny_yolov5.onnx  output "output" [1, 4, 7] in the yolov5 format: a zero 1x1 Conv of the
    globally averaged input, reshaped, plus the constant rows ROWS (below); the output does not
    depend on the input.
tiny_yolov8.onnx  output "output0" [1, 6, 4] in the YOLOv8 / YOLO11 format (no objectness,
    one column per box): built as tiny_yolov5, constant columns ROWS_V8 (below, one row per box
    before the transpose).

Run from this folder:  /usr/bin/python3 make_tiny_models.py
"""
import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

C = 2  # classes
OPSET = 12

# moslam grid constants K[channel, gy, gx]: x, y (offset in cell), w, h (fraction of input),
# objectness (0: it comes from the image), p0, p1.
CELLS = {
    (0, 0): [0.75, 0.5, 0.5, 0.5, 0.0, 0.9, 0.1],
    (0, 1): [0.0, 0.5, 0.5, 0.5, 0.0, 0.8, 0.2],
    (1, 0): [0.75, 0.0, 0.5, 0.5, 0.0, 0.3, 0.7],
    (1, 1): [0.5, 0.5, 0.25, 0.25, 0.0, 0.1, 0.9],
}

# yolov5 rows: cx, cy, w, h (network pixels), objectness, p0, p1.
ROWS = [
    [4.0, 4.0, 4.0, 4.0, 0.9, 0.9, 0.2],
    [4.5, 4.0, 4.0, 4.0, 0.8, 0.7, 0.1],
    [2.0, 6.0, 2.0, 2.0, 0.5, 0.1, 0.8],
    [6.0, 2.0, 2.0, 2.0, 0.5, 0.4, 0.5],
]


# YOLOv8 boxes: cx, cy, w, h (network pixels), p0, p1 (no objectness). The scores are those of
# ROWS (objectness x class probability), so both models detect the same boxes.
ROWS_V8 = [
    [4.0, 4.0, 4.0, 4.0, 0.81, 0.18],
    [4.5, 4.0, 4.0, 4.0, 0.56, 0.08],
    [2.0, 6.0, 2.0, 2.0, 0.05, 0.4],
    [6.0, 2.0, 2.0, 2.0, 0.2, 0.25],
]


def save(graph, path):
    model = helper.make_model(graph, producer_name="moslam-detection-test",
                              opset_imports=[helper.make_opsetid("", OPSET)])
    model.ir_version = 7
    onnx.checker.check_model(model)
    onnx.save(model, path)


def tiny_moslam():
    w = np.zeros((5 + C, 3, 4, 4), np.float32)
    w[4] = 1.0 / 48.0
    k = np.zeros((1, 5 + C, 2, 2), np.float32)
    for (gy, gx), v in CELLS.items():
        k[0, :, gy, gx] = v
    nodes = [
        helper.make_node("Conv", ["images", "W", "B"], ["conv"], kernel_shape=[4, 4],
                         strides=[4, 4]),
        helper.make_node("Add", ["conv", "K"], ["grid"]),
    ]
    graph = helper.make_graph(
        nodes, "tiny_moslam",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, 8, 8])],
        [helper.make_tensor_value_info("grid", TensorProto.FLOAT, [1, 5 + C, 2, 2])],
        [numpy_helper.from_array(w, "W"),
         numpy_helper.from_array(np.zeros(5 + C, np.float32), "B"),
         numpy_helper.from_array(k, "K")])
    save(graph, "tiny_moslam.onnx")


def constant_output(name, reshaped, output, values, path):
    """A model whose output `output` is the constant array `values` (shape [1, ...]): a zero 1x1
    Conv of the globally averaged input, reshaped (tensor `reshaped`), plus the constant."""
    k = np.asarray(values, np.float32)
    size = int(k.size)
    w = np.zeros((size, 3, 1, 1), np.float32)
    nodes = [
        helper.make_node("GlobalAveragePool", ["images"], ["pooled"]),
        helper.make_node("Conv", ["pooled", "W", "B"], ["conv"], kernel_shape=[1, 1]),
        helper.make_node("Reshape", ["conv", "shape"], [reshaped]),
        helper.make_node("Add", [reshaped, "K"], [output]),
    ]
    graph = helper.make_graph(
        nodes, name,
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, 8, 8])],
        [helper.make_tensor_value_info(output, TensorProto.FLOAT, list(k.shape))],
        [numpy_helper.from_array(w, "W"),
         numpy_helper.from_array(np.zeros(size, np.float32), "B"),
         numpy_helper.from_array(np.array(k.shape, np.int64), "shape"),
         numpy_helper.from_array(k, "K")])
    save(graph, path)


def tiny_yolov5():
    constant_output("tiny_yolov5", "rows", "output", [ROWS], "tiny_yolov5.onnx")


def tiny_yolov8():
    constant_output("tiny_yolov8", "columns", "output0",
                    np.array([ROWS_V8], np.float32).transpose(0, 2, 1).copy(), "tiny_yolov8.onnx")


if __name__ == "__main__":
    tiny_moslam()
    tiny_yolov5()
    tiny_yolov8()
    with open("tiny_classes.txt", "w") as f:
        f.write("chair\ntable\n")
