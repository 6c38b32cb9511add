"""Backends of every stage, registered by name with the packages they need.

The table holds only strings, so listing it imports nothing heavy. ``load`` imports a backend on
use and, if a required package is missing, raises ``BackendUnavailable`` naming the exact
``pip install 'coastforge[extra]'`` to run.
"""

from __future__ import annotations

import importlib
import importlib.util
from dataclasses import dataclass
from typing import Any

from .errors import BackendUnavailable, ConfigError


@dataclass(frozen=True)
class BackendSpec:
    stage: str
    name: str
    target: str  # "module:attribute", imported on use
    requires: tuple[str, ...] = ()  # importable module names
    extra: str | None = None  # the coastforge extra that installs them
    needs: str = ""  # what else it needs at run time (weights path, API key), for the listing
    description: str = ""
    default: bool = False


_P = "coastforge."

BACKENDS: tuple[BackendSpec, ...] = (
    # segmentation
    BackendSpec("segment", "classical", _P + "segmentation.classical:ClassicalSegmenter", (), None, "",
                "colour indices, texture, self-trained per-image classifier"),
    BackendSpec("segment", "learned", _P + "segmentation.learned:LearnedSegmenter", ("onnxruntime",), None, "",
                "small U-Net trained by coastforge on its own renders (shipped ONNX), fused with the classical "
                "segmenter", True),
    BackendSpec("segment", "labels", _P + "segmentation.labels:LabelsSegmenter", (), None,
                "--labels FILE and a mapping file", "your own class raster, mapped to our classes"),
    BackendSpec("segment", "onnx", _P + "segmentation.onnx_backend:OnnxSegmenter", ("onnxruntime",), None,
                "--weights model.onnx and a class mapping", "any ONNX segmentation model"),
    BackendSpec("segment", "gemini", _P + "segmentation.gemini:GeminiSegmenter", ("google.genai",), "gemini",
                "GEMINI_API_KEY or GOOGLE_API_KEY", "the paper's method through the Gemini API"),
    # terrain
    BackendSpec("terrain", "default", _P + "terrain.default:DefaultTerrain", (), None, "",
                "shore-aware profiles from the class map (Dean beaches, quay walls, revetments)", True),
    BackendSpec("terrain", "onnx", _P + "terrain.onnx_backend:OnnxTerrain", ("onnxruntime",), None,
                "--weights model.onnx", "a learned height model in ONNX"),
    # detection
    BackendSpec("detect", "classical", _P + "detection.classical:ClassicalDetector", (), None, "",
                "boats, vehicles and piers from colour, contrast and shape; heading from silhouette"),
    BackendSpec("detect", "hybrid", _P + "detection.hybrid:HybridDetector", ("onnxruntime",), None, "",
                "learned boats/vehicles/buoys + classical piers", True),
    BackendSpec("detect", "learned", _P + "detection.learned:LearnedDetector", ("onnxruntime",), None, "",
                "coastforge's own small network trained on synthetic renders (ONNX, shipped)"),
    BackendSpec("detect", "yolo", _P + "detection.yolo:YoloDetector", ("ultralytics", "torch"), "yolo",
                "--weights model.pt (YOLO-OBB)", "ultralytics YOLO-OBB, sliced inference"),
    BackendSpec("detect", "onnx", _P + "detection.onnx_backend:OnnxDetector", ("onnxruntime",), None,
                "--weights model.onnx", "an oriented-box detector exported to ONNX"),
    # embedders (asset library)
    BackendSpec("embed", "default", _P + "assets.embed:DefaultEmbedder", (), None, "",
                "Lab colour, silhouette shape, gradient texture and metric footprint", True),
    BackendSpec("embed", "dinov3", _P + "assets.embed_dinov3:Dinov3Embedder", ("transformers", "torch"),
                "dinov3", "--weights DIR (a local DINOv3 folder)", "DINOv3 ViT features (the paper)"),
    # exporters
    BackendSpec("export", "ue5", _P + "export.ue5:export_ue5", (), None, "", "Unreal Engine 5 level bundle", True),
    BackendSpec("export", "holoocean", _P + "export.holoocean:export_holoocean", (), None, "",
                "HoloOcean scenario and config.json entry", True),
    BackendSpec("export", "gltf", _P + "export.gltf:export_gltf", (), None, "", "binary glTF (GLB)", True),
    BackendSpec("export", "usd", _P + "export.usd:export_usd", ("pxr",), "usd", "",
                "USD stage for Isaac Sim / OceanSim", True),
    BackendSpec("export", "sdf", _P + "export.sdf:export_sdf", (), None, "", "Gazebo / Project DAVE world", True),
    BackendSpec("export", "ue5_tiles", _P + "export.ue5_tiles:export_ue5_tiles", (), None, "",
                "Unreal 5 World-Partition landscape tiles (_x<i>_y<j>) for large terrains"),
    # batches
    BackendSpec("batch", "dask", _P + "batch:run_batch", ("dask", "distributed"), "dask", "",
                "batches of scenes on a dask.distributed cluster", True),
)

STAGES = tuple(dict.fromkeys(b.stage for b in BACKENDS))


def specs(stage: str | None = None) -> list[BackendSpec]:
    return [b for b in BACKENDS if stage is None or b.stage == stage]


def get_spec(stage: str, name: str) -> BackendSpec:
    for b in BACKENDS:
        if b.stage == stage and b.name == name:
            return b
    valid = ", ".join(b.name for b in specs(stage)) or "(none)"
    if stage not in STAGES:
        raise ConfigError(f"unknown stage {stage!r}; stages are: {', '.join(STAGES)}")
    raise ConfigError(f"unknown {stage} backend {name!r}; valid backends: {valid}")


def default_name(stage: str) -> str:
    for b in specs(stage):
        if b.default:
            return b.name
    raise ConfigError(f"stage {stage!r} has no default backend")


def missing_modules(spec: BackendSpec) -> list[str]:
    """Required modules that cannot be imported here (checked without importing them)."""
    out = []
    for mod in spec.requires:
        try:
            found = importlib.util.find_spec(mod) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            out.append(mod)
    return out


def install_hint(spec: BackendSpec) -> str:
    return f"pip install 'coastforge[{spec.extra}]'" if spec.extra else "pip install coastforge"


def is_available(spec: BackendSpec) -> bool:
    return not missing_modules(spec)


def load(stage: str, name: str) -> Any:
    """Import and return a backend's target (class or function)."""
    spec = get_spec(stage, name)
    missing = missing_modules(spec)
    if missing:
        raise BackendUnavailable(
            f"the {stage} backend {name!r} needs {', '.join(missing)}, which is not installed; "
            f"run: {install_hint(spec)}"
        )
    module_name, attr = spec.target.split(":")
    module = importlib.import_module(module_name)
    return getattr(module, attr)


def require(module: str, extra: str, what: str) -> Any:
    """Import an optional package lazily, or fail naming the extra that installs it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise BackendUnavailable(
            f"{what} needs the Python package {module!r} ({exc}); run: pip install 'coastforge[{extra}]'"
        ) from exc
