"""Frozen VGG-16 up to pool2 (conv1_1 … pool2): the feature extractor of the paper's deep LK.

Weights: the ImageNet VGG-16 of Simonyan & Zisserman (CC BY 4.0), as released with Keras, stored
in assets/weights/vgg16_pool2.npz by experiments/extract_vgg16_weights.py (provenance and checksum
in vgg16_pool2.json). Keras VGG expects BGR in 0–255 minus per-channel means. torchvision's
`vgg16-397923af.pth` (RGB, ImageNet mean/std, a different training) is accepted too.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import torch
from torch import nn

from hvs_sim.errors import WeightsError
from hvs_sim.paths import WEIGHTS_DIR

VGG_NPZ = WEIGHTS_DIR / "vgg16_pool2.npz"
LAYERS = ("conv1_1", "conv1_2", "conv2_1", "conv2_2")
SHAPES = {"conv1_1": (64, 3, 3, 3), "conv1_2": (64, 64, 3, 3), "conv2_1": (128, 64, 3, 3), "conv2_2": (128, 128, 3, 3)}
KERAS_BGR_MEAN = (103.939, 116.779, 123.68)
TORCHVISION_MEAN, TORCHVISION_STD = (0.485, 0.456, 0.406), (0.229, 0.224, 0.225)
STRIDES = {"conv1_2": 1, "pool1": 2, "pool2": 4}  # level name → stride in input pixels
# oneDNN runs these 3×3 convolutions faster on channels-last (NHWC) tensors, and the feature LK reads
# its maps channels-last (feature_lk.channels_last: then without a copy); values agree to ~1e-6 relative
CHANNELS_LAST = True
# on CPU, each conv + ReLU as one oneDNN primitive (the op PyTorch's own compiler emits): the same
# values bit for bit, one pass and one parallel region fewer per layer. Each parallel region of the
# two torch threads is a barrier, and a barrier waits for a time slice when another process holds a
# core (measured with the machine loaded: 76 ms against 116 ms per forward pass)
FUSED_CONV_RELU = True


def _fused_available() -> bool:
    return (FUSED_CONV_RELU and torch.backends.mkldnn.is_available()
            and hasattr(torch.ops.mkldnn, "_convolution_pointwise"))


def sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


class VGG16Pool2(nn.Module):
    """conv1_1 → conv1_2 → pool1 → conv2_1 → conv2_2 → pool2, returning the requested levels.

    Input: a grey image batch (N, 1, H, W) with values 0–255; it is replicated to three channels
    and normalised the way the loaded weights expect.
    """

    def __init__(self, weights: dict[str, tuple[np.ndarray, np.ndarray]], flavour: str = "keras"):
        super().__init__()
        self.convs = nn.ModuleDict()
        for name in LAYERS:
            w, b = weights[name]
            conv = nn.Conv2d(w.shape[1], w.shape[0], 3, padding=1)
            conv.weight.data = torch.from_numpy(np.ascontiguousarray(w, np.float32))
            conv.bias.data = torch.from_numpy(np.ascontiguousarray(b, np.float32))
            self.convs[name] = conv
        if flavour == "keras":  # BGR order, matching the kernel's input channels; 0–255 minus means
            mean, scale = torch.tensor(KERAS_BGR_MEAN), torch.ones(3)
        elif flavour == "torchvision":  # RGB in 0–1, ImageNet mean/std
            mean = torch.tensor(TORCHVISION_MEAN) * 255.0
            scale = 1.0 / (torch.tensor(TORCHVISION_STD) * 255.0)
        else:
            raise WeightsError(f"unknown VGG weight flavour {flavour!r}; accepted: keras, torchvision")
        self.register_buffer("mean", mean.reshape(1, 3, 1, 1))
        self.register_buffer("scale", scale.reshape(1, 3, 1, 1))
        self.flavour = flavour
        self.requires_grad_(False)
        if CHANNELS_LAST:
            self.to(memory_format=torch.channels_last)
        self.fused = _fused_available()
        self.eval()

    def _conv_relu(self, x: torch.Tensor, name: str) -> torch.Tensor:
        conv = self.convs[name]
        if self.fused and x.device.type == "cpu" and x.dtype == torch.float32 and not (
                torch.is_grad_enabled() and x.requires_grad):
            try:
                return torch.ops.mkldnn._convolution_pointwise(x, conv.weight, conv.bias, [1, 1], [1, 1], [1, 1], 1,
                                                               "relu", [None], None)
            except RuntimeError:  # an op this torch build does not carry after all: eager from now on
                self.fused = False
        # in-place ReLU: the conv output is fresh, so this saves an allocation
        return torch.relu_(conv(x))

    def forward(self, grey: torch.Tensor, levels=("pool2",)) -> dict[str, torch.Tensor]:
        out = {}
        rgb = (grey.expand(-1, 3, -1, -1) - self.mean) * self.scale  # grey replicated to 3 channels
        if CHANNELS_LAST:
            rgb = rgb.contiguous(memory_format=torch.channels_last)
        x = self._conv_relu(rgb, "conv1_1")
        x = self._conv_relu(x, "conv1_2")
        out["conv1_2"] = x
        x = nn.functional.max_pool2d(x, 2)
        out["pool1"] = x
        if "pool2" in levels:
            x = self._conv_relu(x, "conv2_1")
            x = self._conv_relu(x, "conv2_2")
            out["pool2"] = nn.functional.max_pool2d(x, 2)
        return {k: out[k] for k in levels}


def load_weights(path: Path | str | None = None) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], str]:
    """Read conv1_1…conv2_2 from our .npz (Keras flavour) or torchvision's vgg16-397923af.pth."""
    from hvs_sim.validate import check_regular_file

    path = Path(path) if path is not None else VGG_NPZ
    if not path.exists() and not path.is_symlink():
        raise WeightsError(f"VGG-16 weights not found at {path}; run `python experiments/extract_vgg16_weights.py` "
                           "or pass the path of torchvision's vgg16-397923af.pth")
    check_regular_file(path, "VGG-16 weights", WeightsError)  # a FIFO would block the read forever
    weights: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    if path.suffix == ".npz":
        flavour = "keras"
        try:
            data = np.load(path)  # allow_pickle=False: an object array (a pickle) is refused, never run
            for name in LAYERS:
                if f"{name}_w" not in data or f"{name}_b" not in data:
                    raise WeightsError(f"{path} lacks {name}_w/{name}_b; it is not an hvs_sim VGG-16 weights file")
                weights[name] = (data[f"{name}_w"], data[f"{name}_b"])
        except WeightsError:
            raise
        except Exception as exc:  # noqa: BLE001 - numpy raises many kinds for a damaged or hostile file
            raise WeightsError(f"{path} is not a readable .npz of plain arrays ({type(exc).__name__}: {exc}); "
                               "object arrays (pickles) are refused") from None
    elif path.suffix in (".pth", ".pt"):
        try:
            state = torch.load(path, map_location="cpu", weights_only=True)  # weights_only: no pickled code runs
        except Exception as exc:  # noqa: BLE001 - torch raises many kinds for a damaged or hostile file
            raise WeightsError(f"{path} is not a readable torch weights file ({type(exc).__name__}: "
                               f"{str(exc).splitlines()[0] if str(exc) else ''}); only tensors are loaded, pickled "
                               "objects are refused") from None
        flavour = "torchvision"
        for name, idx in zip(LAYERS, (0, 2, 5, 7)):
            try:
                weights[name] = (state[f"features.{idx}.weight"].numpy(), state[f"features.{idx}.bias"].numpy())
            except KeyError as exc:
                raise WeightsError(f"{path} has no key {exc}; expected torchvision VGG-16 keys features.0 … features.7") from None
    else:
        raise WeightsError(f"unsupported weights file {path.name}; accepted: .npz (hvs_sim) or .pth (torchvision)")
    for name in LAYERS:
        w, b = weights[name]
        if tuple(w.shape) != SHAPES[name] or tuple(b.shape) != (SHAPES[name][0],):
            raise WeightsError(f"{path}: {name} has shape {tuple(w.shape)}/{tuple(b.shape)}, expected {SHAPES[name]}")
    return weights, flavour


_CACHE: dict[str, VGG16Pool2] = {}


def vgg16_pool2(path: Path | str | None = None) -> VGG16Pool2:
    """The frozen extractor (cached per weights file)."""
    key = str(Path(path).resolve()) if path is not None else str(VGG_NPZ)
    if key not in _CACHE:
        weights, flavour = load_weights(path)
        _CACHE[key] = VGG16Pool2(weights, flavour)
    return _CACHE[key]
