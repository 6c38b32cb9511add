"""The page's building blocks: pictures as data URIs, figures, tables, notes, and its static files."""

from __future__ import annotations

import base64
import html
from importlib import resources

import numpy as np

MAX_PX = 1400  # big pictures are shown at most this wide: keeps a 100-object report far under 15 MB


def data_uri(rgb: np.ndarray, fmt: str = "jpeg", quality: int = 85) -> str:
    import cv2

    a = rgb if rgb.ndim == 2 else np.ascontiguousarray(rgb[:, :, ::-1])
    ok, buf = cv2.imencode(".jpg" if fmt == "jpeg" else ".png", a,
                           [cv2.IMWRITE_JPEG_QUALITY, quality] if fmt == "jpeg" else [])
    if not ok:
        raise OSError("could not encode an image for the report")
    return f"data:image/{fmt};base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def fit(rgb: np.ndarray, max_px: int = MAX_PX) -> np.ndarray:
    import cv2

    h, w = rgb.shape[:2]
    s = min(1.0, max_px / max(h, w))
    if s >= 1.0:
        return rgb
    return cv2.resize(rgb, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)


def upscale_small(rgb: np.ndarray, min_px: int = 700) -> np.ndarray:
    """Small images (tests, tiny scenes) upscaled with nearest pixels: overlays drawn on them stay legible."""
    import cv2

    f = int(np.ceil(min_px / max(rgb.shape[:2])))
    if f <= 1:
        return rgb
    return cv2.resize(rgb, (rgb.shape[1] * f, rgb.shape[0] * f), interpolation=cv2.INTER_NEAREST)


def resize_to(a: np.ndarray, shape: tuple[int, int], nearest: bool = False) -> np.ndarray:
    import cv2

    if a.shape[:2] == shape:
        return a
    return cv2.resize(a, (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST if nearest else cv2.INTER_AREA)


def figure(uri: str, caption: str, cls: str = "") -> str:
    return (f'<figure class="{cls}"><img decoding="async" src="{uri}" alt="{html.escape(caption)}" '
            'title="click to enlarge"/>'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def table(header: list[str] | None, rows: list[list], cls: str = "") -> str:
    th = "<thead><tr>" + "".join(f"<th>{h}</th>" for h in header) + "</tr></thead>" if header else ""
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="{cls}">{th}<tbody>{body}</tbody></table>'


def fmt_value(v, nd: int = 3) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (float, np.floating)):
        return "—" if not np.isfinite(v) else f"{float(v):.{nd}f}"
    return html.escape(str(v))


def note(text: str) -> str:
    return f'<p class="note">{text}</p>'


def rgb_css(c) -> str:
    return "rgb({},{},{})".format(*(int(v) for v in c))


def static_text(name: str) -> str:
    """A file of ``report/static``: the page's stylesheet and script, the 3D viewer bundle and its licence."""
    return resources.files(__package__).joinpath("static").joinpath(name).read_text(encoding="utf-8")
