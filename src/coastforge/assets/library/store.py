"""A built library on disk (``Library``): its records, index, meshes and views, and the search over them."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any
from collections.abc import Sequence

import numpy as np

from ...classes import ASSET_CATEGORIES
from ...errors import InputError, LibraryError
from ...fsio import read_png
from ..index import VectorIndex
from ..meshes import load_mesh

if TYPE_CHECKING:  # pragma: no cover
    from .build import BuildReport

FORMAT = "coastforge.library/1"


Z_UP_TO_GLTF = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 0], [0, 0, 0, 1.0]])


LIBRARY_JSON = "library.json"


INDEX_FILE = "index.faiss"


@dataclass(frozen=True)
class AssetRecord:
    """One asset of a library. ``mesh_path`` is the normalised GLB (None for thumbnail-only assets)."""

    id: str
    category: str
    dims_m: tuple[float, float, float]  # length (x, forward), width (y), height (z)
    draft_m: float  # depth of the hull below the waterline (floating assets)
    floating: bool
    ue_path: str | None
    mesh_path: Path | None
    views: tuple[Path, ...]  # PNGs, in the order of ``view_conditions``
    view_gsd_m: float  # metres per pixel of every view of this asset
    tags: tuple[str, ...] = ()
    view_conditions: tuple[str, ...] = ()  # "l<k>_<background>" per view
    mesh_up: str = "z"  # "y": the GLB follows glTF's y-up convention (libraries built since this field exists)
    silhouette_path: Path | None = None  # footprint mask aligned with the views (libraries built since it exists)

    @property
    def length_m(self) -> float:
        return self.dims_m[0]


def canonical(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def sha(*parts: Any) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p if isinstance(p, bytes) else canonical(p).encode())
    return h.hexdigest()


class Library:
    """A built library on disk. Load with ``Library.load(path)``."""

    def __init__(self, root: Path, doc: dict, assets: tuple[AssetRecord, ...], index: VectorIndex,
                 weights: str | None = None, report: BuildReport | None = None):
        self.root = Path(root)
        self.doc = doc
        self.assets = assets
        self._by_id = {a.id: i for i, a in enumerate(assets)}
        self.index = index
        self._weights = weights
        self._embedder = None
        self._meshes: dict[str, Any] = {}
        self.build_report = report

    # -- loading
    @classmethod
    def load(cls, path: str | Path, embedder: str | None = None, weights: str | Path | None = None,
             check_files: bool = True) -> Library:
        """Open a library folder (or its library.json). ``embedder`` (a name) must match the one it was built
        with; ``weights`` overrides the recorded weights folder of a weights-based embedder. ``check_files``:
        refuse a library missing a file it lists (a view, a silhouette, a model copy)."""
        root = Path(path)
        if root.is_file() and root.name == LIBRARY_JSON:
            root = root.parent
        jpath = root / LIBRARY_JSON
        if not jpath.is_file():
            raise LibraryError(f"{root} is not an asset library (no {LIBRARY_JSON}); build one with "
                               "`coastforge library build SRC --out DIR`")
        try:
            doc = json.loads(jpath.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise LibraryError(f"{jpath} is not readable JSON ({exc}); rebuild the library") from exc
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
            raise LibraryError(f"{jpath}: format {got!r} is not {FORMAT!r}; rebuild the library with this version")
        try:
            emb = doc["embedder"]
            assets, row_asset = [], []
            for i, a in enumerate(doc["assets"]):
                _start, count = a["index_rows"]
                row_asset.extend([i] * int(count))
                assets.append(_record_from_json(root, a))
            idx_info = doc["index"]
            if len(row_asset) != int(idx_info["rows"]):
                raise ValueError(f"assets claim {len(row_asset)} index rows but the index has {idx_info['rows']}")
            starts = [a["index_rows"][0] for a in doc["assets"]]
            if starts != sorted(starts) or (starts and starts[0] != 0):
                raise ValueError("index rows are not contiguous per asset")
        except (KeyError, TypeError, ValueError) as exc:
            raise LibraryError(f"{jpath} is malformed ({type(exc).__name__}: {exc}); rebuild the library") from exc
        if embedder is not None and embedder != emb["name"]:
            raise LibraryError(
                f"library {root} was built with the {emb['name']!r} embedder, not {embedder!r}; query it with "
                f"--embedder {emb['name']} or rebuild it with --embedder {embedder}"
            )
        index = VectorIndex.load(root / idx_info["file"], row_asset, int(emb["dim"]), idx_info.get("sha256"))
        if check_files:
            missing = [(a["id"], f) for a in doc["assets"] for f in record_files(a) if not (root / f).is_file()]
            if missing:
                shown = ", ".join(f"{f} (asset {aid!r})" for aid, f in missing[:3])
                raise LibraryError(f"library {root} is incomplete: {len(missing)} file(s) it lists are missing, "
                                   f"e.g. {shown}; rebuild it (coastforge library build SRC --out {root}: only "
                                   "the damaged assets are rendered again)")
        return cls(root, doc, tuple(assets), index, str(weights) if weights is not None else emb.get("weights"))

    # -- assets
    def asset(self, asset_id: str) -> AssetRecord:
        try:
            return self.assets[self._by_id[asset_id]]
        except KeyError:
            raise LibraryError(f"asset {asset_id!r} is not in library {self.root}; it has "
                               f"{len(self.assets)} assets, e.g. {', '.join(list(self._by_id)[:8])}") from None

    def __contains__(self, asset_id: str) -> bool:
        return asset_id in self._by_id

    def __len__(self) -> int:
        return len(self.assets)

    def mesh(self, asset_id: str):
        """The asset's mesh in the scene frame (a copy). Thumbnail-only assets get a box of their bounds."""
        import trimesh

        a = self.asset(asset_id)
        if asset_id not in self._meshes:
            if a.mesh_path is None:
                L, W, H = a.dims_m
                box = trimesh.creation.box(extents=(L, W, H))
                box.apply_translation([0, 0, H / 2 - a.draft_m])
                box.visual.face_colors = np.array([150, 150, 150, 255], np.uint8)
                self._meshes[asset_id] = box
            else:
                try:
                    m = load_mesh(a.mesh_path, asset_id)
                except LibraryError as exc:  # the library's own copy: the user did not write that file
                    raise LibraryError(f"asset {asset_id!r}: the library's copy of its model, {a.mesh_path}, is "
                                       f"missing or unreadable ({exc}); rebuild the library (coastforge library "
                                       f"build SRC --out {self.root})") from None
                if a.mesh_up == "y":  # stored in glTF's y-up convention: back to the scene frame
                    m.apply_transform(np.linalg.inv(Z_UP_TO_GLTF))
                self._meshes[asset_id] = m
        return self._meshes[asset_id].copy()

    def view(self, asset_id: str, lighting: int = 1, background: str = "water") -> tuple[np.ndarray, float]:
        """One top-down view (RGB uint8, forward = image right) and its metres per pixel."""
        a = self.asset(asset_id)
        key = f"l{lighting}_{background}"
        if key not in a.view_conditions:
            key = next((c for c in a.view_conditions if c.endswith(background)), a.view_conditions[0])
        p = a.views[a.view_conditions.index(key)]
        try:
            return read_png(p), a.view_gsd_m
        except InputError as exc:
            raise LibraryError(f"asset {asset_id!r}: view {p} is missing or unreadable; rebuild the library") from exc

    def views_on(self, asset_id: str, background: str) -> list[np.ndarray]:
        """Every stored view of the asset on ``background`` (lightings and repainted copies), all at
        ``view_gsd_m``; falls back to the views on the other background when none match."""
        self.asset(asset_id)  # a clear error for an unknown id
        rec = self.doc["assets"][self._by_id[asset_id]]
        files = [v["file"] for v in rec.get("views", []) + rec.get("paint_views", []) if v["background"] == background]
        if not files:
            files = [v["file"] for v in rec.get("views", [])]
        out = []
        for f in files:
            try:
                img = read_png(self.root / f)
            except InputError as exc:
                raise LibraryError(f"asset {asset_id!r}: view {self.root / f} is missing or unreadable; rebuild the "
                                   "library") from exc
            out.append(img[:, :, :3] if img.ndim == 3 else np.repeat(img[:, :, None], 3, axis=2))
        if not out:
            raise LibraryError(f"asset {asset_id!r} has no views in {self.root}; rebuild the library")
        return out

    def silhouette(self, asset_id: str) -> np.ndarray | None:
        """The asset's footprint seen from above, aligned with its views (float32 0/1), or None when the
        library has none stored (thumbnail assets, libraries built before silhouettes were stored)."""
        p = self.asset(asset_id).silhouette_path
        if p is None:
            return None
        try:
            return (read_png(p) > 127).astype(np.float32)
        except InputError as exc:
            raise LibraryError(f"the silhouette of asset {asset_id!r} ({p}) is unreadable; rebuild the library") from exc

    def top_view(self, asset_id: str, background: str = "water") -> tuple[np.ndarray, float]:
        """The noon-light view on ``background`` (what the matcher compares a crop's heading against)."""
        return self.view(asset_id, 1, background)

    # -- embedding and search
    @property
    def embedder_name(self) -> str:
        return self.doc["embedder"]["name"]

    @property
    def embedder(self):
        """The embedder that built this library (created on first use; its settings are checked)."""
        if self._embedder is None:
            emb = make_embedder(self.embedder_name, self._weights)
            self.check_embedder(emb)
            self._embedder = emb
        return self._embedder

    @embedder.setter
    def embedder(self, emb) -> None:
        """The embedder a build just used (it made this library's rows: no second one is created)."""
        self._embedder = emb

    def check_embedder(self, emb) -> None:
        rec = self.doc["embedder"]
        old_v = rec.get("settings", {}).get("version") if isinstance(rec.get("settings"), dict) else None
        new_v = emb.settings.get("version") if isinstance(emb.settings, dict) else None
        if emb.name == rec["name"] and old_v != new_v:
            raise LibraryError(
                f"library {self.root} was embedded with version {old_v} of the {emb.name!r} embedder, this is "
                f"version {new_v}: its vectors are not comparable; rebuild it from its models (coastforge library "
                f"build SRC --out {self.root})"
            )
        if emb.name != rec["name"] or canonical(emb.settings) != canonical(rec["settings"]) or emb.dim != rec["dim"]:
            raise LibraryError(
                f"library {self.root} was embedded with {rec['name']!r} (settings {canonical(rec['settings'])[:120]}"
                f"...), not with {emb.name!r} (settings {canonical(emb.settings)[:120]}...); query it with the same "
                "embedder and weights or rebuild it"
            )

    def embed(self, images: Sequence[np.ndarray], gsd_m: Sequence[float]) -> np.ndarray:
        return self.embedder.embed(list(images), list(gsd_m))

    def _allowed(self, category) -> np.ndarray | None:
        if category is None:
            return None
        cats = {category} if isinstance(category, str) else set(category)
        bad = cats - set(ASSET_CATEGORIES)
        if bad:
            raise LibraryError(f"unknown category {sorted(bad)}; use one of {', '.join(ASSET_CATEGORIES)}")
        return np.array([a.category in cats for a in self.assets], bool)

    # Category vote for searches over all categories: the category of the first hit is the one with the
    # most evidence, sum over its assets of exp((cosine - best) / T) (the category's posterior when every
    # asset is a priori as likely and exp(cosine / T) is its likelihood), not the category of the single
    # best asset, which a lone look-alike of another category can take. 0 turns it off. T tuned on the
    # retrieval benchmark, seeds 0-2, 3-4 held out (figures: docs/benchmarks.md). T is in units of the default
    # embedder's cosine; libraries of other embedders keep the plain ranking until T is calibrated for them.
    CATEGORY_VOTE_T = 0.03
    CATEGORY_VOTE_EMBEDDERS = ("default",)
    # The vote is weighed by the category head's posteriors to this power (``category_prior``; 0: off).
    # Tuned on the retrieval benchmark: 0.5 improves all three sets (rendered queries, synthetic-scene crops,
    # real photos); at 1 and above the head alone decides more, which costs the real crops.
    CATEGORY_PRIOR_BETA = 0.5

    def category_prior(self, images: Sequence[np.ndarray], gsd_m: Sequence[float]) -> np.ndarray | None:
        """The category head's posteriors of crops over this library's categories (sorted names), to weigh
        the category vote of ``search``; None when it does not apply (another embedder, one category, the
        head switched off or not installed)."""
        from ..category_net import CATEGORIES, shipped_head

        names = sorted({a.category for a in self.assets})
        if self.CATEGORY_PRIOR_BETA <= 0 or len(names) < 2 or \
                self.doc.get("embedder", {}).get("name") not in self.CATEGORY_VOTE_EMBEDDERS:
            return None
        head = shipped_head()
        if head is None:
            return None
        post = head.posteriors(images, gsd_m)
        cols = [CATEGORIES.index(c) for c in names]
        prior = post[:, cols] + 1e-6
        return prior / prior.sum(1, keepdims=True)

    def search(self, vectors: np.ndarray, k: int = 5, category: str | Sequence[str] | None = None,
               prior: np.ndarray | None = None) -> list[list[tuple[str, float]]]:
        """Per query vector, the ``k`` best assets as (asset_id, cosine), best first. Without ``category``
        the first hit is the best asset of the category voted for (see ``CATEGORY_VOTE_T``), weighed by
        ``prior`` (per query, over the sorted category names: ``category_prior``) when given; the rest
        follow by cosine."""
        cats = [a.category for a in self.assets]
        if category is None and self.CATEGORY_VOTE_T > 0 and len(set(cats)) > 1 and self.index.rows \
                and self.doc.get("embedder", {}).get("name") in self.CATEGORY_VOTE_EMBEDDERS:
            if int(k) < 1:
                raise LibraryError(f"k = {k} must be at least 1")
            vectors = np.asarray(vectors, np.float32)
            if prior is not None and np.shape(prior) != (len(vectors), len(set(cats))):
                raise LibraryError(f"prior of shape {np.shape(prior)} for {len(vectors)} queries and "
                                   f"{len(set(cats))} categories")
            return self._voted_search(vectors, int(k), cats, prior)
        hits = self.index.search(np.asarray(vectors, np.float32), int(k), self._allowed(category))
        return [[(self.assets[i].id, s) for i, s in row] for row in hits]

    def _voted_search(self, vectors: np.ndarray, k: int, cats: list[str], prior: np.ndarray | None = None
                      ) -> list[list[tuple[str, float]]]:
        scores = self.index.asset_scores(vectors, len(self.assets))
        names = sorted(set(cats))
        cat_of = np.array([names.index(c) for c in cats])
        out = []
        for q, row in enumerate(scores):
            have = np.isfinite(row)
            order = [int(i) for i in np.argsort(-row, kind="stable") if have[i]]
            w = np.where(have, np.exp((row - row[order[0]]) / self.CATEGORY_VOTE_T), 0.0)
            evidence = np.bincount(cat_of, weights=w, minlength=len(names))
            if prior is not None:
                evidence = evidence * np.power(prior[q], self.CATEGORY_PRIOR_BETA)
            voted = int(np.argmax(evidence))
            first = next(i for i in order if cat_of[i] == voted)
            ranked = [first] + [i for i in order if i != first]
            out.append([(self.assets[i].id, float(row[i])) for i in ranked[:k]])
        return out

    def query(self, image: np.ndarray, gsd_m: float, k: int = 5, category: str | Sequence[str] | None = None
              ) -> list[tuple[str, float]]:
        """The ``k`` assets most like one crop (object centred, any rotation)."""
        prior = self.category_prior([image], [gsd_m]) if category is None else None
        return self.search(self.embed([image], [gsd_m]), k, category, prior)[0]


def record_files(a: dict) -> list[str]:
    """The files (relative to the library) one asset record of library.json lists."""
    files = [v["file"] for v in a.get("views", []) + a.get("paint_views", [])]
    files += [a[k] for k in ("silhouette", "mesh", "query_views_file") if a.get(k)]
    return files


def _record_from_json(root: Path, a: dict) -> AssetRecord:
    views = tuple(root / v["file"] for v in a["views"])
    conds = tuple(f"l{int(v['lighting'])}_{v['background']}" for v in a["views"])
    dims = tuple(float(v) for v in a["dims_m"])
    if len(dims) != 3 or min(dims) <= 0:
        raise ValueError(f"asset {a.get('id')!r}: dims_m {a['dims_m']!r} must be three positive numbers")
    return AssetRecord(
        id=str(a["id"]), category=str(a["category"]), dims_m=dims, draft_m=float(a.get("draft_m", 0.0)),
        floating=bool(a.get("floating", False)), ue_path=a.get("ue_path"),
        mesh_path=(root / a["mesh"]) if a.get("mesh") else None, views=views, view_gsd_m=float(a["view_gsd_m"]),
        tags=tuple(a.get("tags", ())), view_conditions=conds, mesh_up=str(a.get("mesh_up", "z")),
        silhouette_path=(root / a["silhouette"]) if a.get("silhouette") else None,
    )


def make_embedder(name: str, weights: str | None = None):
    from ... import registry

    cls = registry.load("embed", name)
    return cls(weights=weights)
