"""The paper's method through the Gemini API (``google-genai``): two image-to-image requests.

1. "Remove every boat, car and other transient object" → a cleaned image.
2. "Paint this image as a class map in exactly these eight colours" → a class image, snapped to our
   palette (models paint anti-aliased or slightly off colours) and resized to the scene grid.

The API key comes from ``GEMINI_API_KEY`` or ``GOOGLE_API_KEY``. Nothing is sent unless this backend is
chosen explicitly. Tests inject a fake ``client`` with ``client.models.generate_content(...)``.
"""

from __future__ import annotations

import base64
import io
import os

import cv2
import numpy as np

from ..classes import TERRAIN_CLASSES, snap_to_palette
from ..config import SegmentConfig
from ..errors import BackendUnavailable, InputError
from ..registry import require
from ..types import ClassMap, GeoImage

DEFAULT_MODEL = "gemini-2.5-flash-image"

CLEAN_PROMPT = (
    "This is an overhead (nadir) aerial image of a coastline. Remove every boat, ship, car, truck and other "
    "vehicle, and fill where each one was with the surface under it (water under boats, pavement under "
    "cars), matching the surrounding colour and texture. Keep piers, docks, buildings, roads, vegetation, "
    "rocks and the shoreline exactly where they are. Do not change the framing, scale or size of the image. "
    "Return only the edited image."
)


def class_prompt() -> str:
    lines = [f"- {c.name}: RGB({c.rgb[0]}, {c.rgb[1]}, {c.rgb[2]}) #{c.rgb[0]:02x}{c.rgb[1]:02x}{c.rgb[2]:02x}"
             for c in TERRAIN_CLASSES]
    return (
        "Segment this overhead aerial image of a coastline into exactly eight terrain classes and return a "
        "flat colour class map of the same framing and aspect ratio: every pixel painted in exactly one of "
        "these colours, no shading, no outlines, no text, no legend:\n" + "\n".join(lines) + "\n"
        "Water includes the water under piers and boats. Sidewalk includes parking lines, paths and plazas. "
        "Buildings take the class of the ground around them."
    )


def encode_png(rgb: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(rgb[:, :, ::-1]))
    if not ok:
        raise InputError("could not encode the image as PNG for the Gemini request")
    return buf.tobytes()


def decode_image(data) -> np.ndarray:
    """Bytes (or base64 text) of a PNG/JPEG/WebP → (H, W, 3) uint8 RGB."""
    from PIL import Image, UnidentifiedImageError

    if isinstance(data, str):
        data = base64.b64decode(data)
    try:
        with Image.open(io.BytesIO(bytes(data))) as im:
            return np.asarray(im.convert("RGB"))
    except (UnidentifiedImageError, OSError) as exc:
        raise BackendUnavailable(f"Gemini returned image data that cannot be decoded ({exc})") from exc


def first_image(response) -> np.ndarray:
    """The first inline image of a ``generate_content`` response (candidates → content → parts)."""
    texts = []
    parts = []
    for cand in getattr(response, "candidates", None) or []:
        content = getattr(cand, "content", None)
        parts.extend(getattr(content, "parts", None) or [])
    if not parts:
        parts = list(getattr(response, "parts", None) or [])
    for part in parts:
        blob = getattr(part, "inline_data", None)
        if blob is not None and getattr(blob, "data", None):
            return decode_image(blob.data)
        if getattr(part, "text", None):
            texts.append(part.text)
    said = (" It said: " + " ".join(texts)[:300]) if texts else ""
    raise BackendUnavailable(f"Gemini returned no image.{said} Try again, or use another --backend.")


def parse_class_image(rgb: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A painted class image → class ids on a (H, W) grid: snap each pixel to the nearest palette
    colour at the painted resolution, clean single-pixel speckle (anti-aliased edges), resize nearest."""
    ids = snap_to_palette(rgb)
    ids = cv2.medianBlur(ids, 3)
    H, W = shape
    if ids.shape != (H, W):
        ids = cv2.resize(ids, (W, H), interpolation=cv2.INTER_NEAREST)
    return ids.astype(np.uint8)


class GeminiSegmenter:
    """Two Gemini requests: remove transient objects, then paint the class map in our palette."""

    def __init__(self, config: SegmentConfig | None = None, client=None, model: str = DEFAULT_MODEL,
                 api_key: str | None = None, clean: bool = True, **options):
        if options:
            raise InputError(f"the gemini segmenter takes client=, model=, api_key=, clean=, not {', '.join(sorted(options))}")
        self.config = config or SegmentConfig()
        self.client = client
        self.model = model
        self.api_key = api_key
        self.clean = clean
        self.cleaned: np.ndarray | None = None  # the cleaned image of the last call (for textures)

    def _client(self):
        if self.client is not None:
            return self.client
        key = self.api_key or os.environ.get("GEMINI_API_KEY") or os.environ.get("GOOGLE_API_KEY")
        if not key:
            raise BackendUnavailable(
                "the gemini backend needs an API key: set GEMINI_API_KEY (or GOOGLE_API_KEY), "
                "or use an offline backend: --backend learned (the default) or classical"
            )
        genai = require("google.genai", "gemini", "the gemini segmenter")
        self.client = genai.Client(api_key=key)
        return self.client

    def _request(self, client, prompt: str, rgb: np.ndarray, seed: int) -> np.ndarray:
        png = encode_png(rgb)
        try:
            from google.genai import types
        except ImportError:  # an injected client without the SDK: plain dicts are what the SDK accepts too
            contents = [prompt, {"inline_data": {"mime_type": "image/png", "data": png}}]
            config = {"response_modalities": ["IMAGE", "TEXT"], "seed": int(seed) % (2**31)}
        else:
            contents = [prompt, types.Part.from_bytes(data=png, mime_type="image/png")]
            config = types.GenerateContentConfig(response_modalities=["IMAGE", "TEXT"], seed=int(seed) % (2**31))
        try:
            response = client.models.generate_content(model=self.model, contents=contents, config=config)
        except BackendUnavailable:
            raise
        except Exception as exc:  # network, quota, auth: the SDK raises many types
            raise BackendUnavailable(f"the Gemini request to {self.model} failed: {exc}") from exc
        return first_image(response)

    def remove_transients(self, rgb: np.ndarray, seed: int = 0) -> np.ndarray:
        """Request 1: the image with boats and vehicles removed, resized back to the input size."""
        out = self._request(self._client(), CLEAN_PROMPT, rgb, seed)
        if out.shape[:2] != rgb.shape[:2]:
            out = cv2.resize(out, (rgb.shape[1], rgb.shape[0]), interpolation=cv2.INTER_CUBIC)
        return out

    def segment(self, image: GeoImage, seed: int = 0) -> ClassMap:
        client = self._client()
        rgb = image.rgb
        if self.clean:
            rgb = self.remove_transients(rgb, seed)
            self.cleaned = rgb
        painted = self._request(client, class_prompt(), rgb, seed)
        ids = parse_class_image(painted, image.grid.shape)
        return ClassMap(ids=ids, grid=image.grid)


__all__ = ["CLEAN_PROMPT", "GeminiSegmenter", "class_prompt", "first_image", "parse_class_image"]
