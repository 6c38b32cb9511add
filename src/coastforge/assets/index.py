"""The library's vector index: FAISS inner product over L2-normalised embeddings (= cosine similarity).

Each row is one view of one asset (several lightings, backgrounds and scales per asset); a search
returns assets ranked by their best-matching row.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from collections.abc import Sequence

import numpy as np

from ..errors import LibraryError
from ..fsio import atomic_path


class VectorIndex:
    """Rows of unit vectors, each labelled with the position of its asset in the library."""

    def __init__(self, vectors: np.ndarray, row_asset: Sequence[int]):
        import faiss

        v = np.ascontiguousarray(vectors, dtype=np.float32)
        if v.ndim != 2 or v.shape[0] != len(row_asset):
            raise LibraryError(f"index has {v.shape} vectors for {len(row_asset)} row labels; rebuild the library")
        if v.shape[0] and not np.all(np.isfinite(v)):
            raise LibraryError("index holds non-finite vectors; rebuild the library")
        self.dim = int(v.shape[1])
        self.row_asset = np.asarray(row_asset, dtype=np.int64)
        # rows grouped by asset, for best-row-per-asset scores in one vectorised pass
        self._order = np.argsort(self.row_asset, kind="stable")
        sorted_assets = self.row_asset[self._order]
        self._starts = np.flatnonzero(np.r_[True, sorted_assets[1:] != sorted_assets[:-1]]) if len(v) else \
            np.zeros(0, np.intp)
        self._start_asset = sorted_assets[self._starts] if len(v) else np.zeros(0, np.int64)
        self.index = faiss.IndexFlatIP(self.dim)
        if len(v):
            self.index.add(v)

    @property
    def rows(self) -> int:
        return int(self.index.ntotal)

    def vectors(self) -> np.ndarray:
        if self.rows == 0:
            return np.zeros((0, self.dim), np.float32)
        return self.index.reconstruct_n(0, self.rows)

    def search(self, queries: np.ndarray, k: int, allowed: np.ndarray | None = None) -> list[list[tuple[int, float]]]:
        """Top ``k`` assets per query as (asset position, best cosine), best first.

        ``allowed`` is a boolean mask over asset positions (e.g. one category).
        """
        q = self._check_queries(queries)
        if k < 1:
            raise LibraryError(f"k = {k} must be at least 1")
        if self.rows == 0:
            return [[] for _ in range(len(q))]
        # Flat index: scoring every row is exact and cheap for library sizes (thousands of rows).
        scores, ids = self.index.search(q, self.rows)
        out = []
        for srow, irow in zip(scores, ids):
            best: dict[int, float] = {}
            for s, i in zip(srow, irow):
                if i < 0:
                    continue
                a = int(self.row_asset[i])
                if allowed is not None and not allowed[a]:
                    continue
                if a not in best:
                    best[a] = float(s)
                    if len(best) >= k:
                        break
            out.append(sorted(best.items(), key=lambda t: -t[1]))
        return out

    def asset_scores(self, queries: np.ndarray, n_assets: int) -> np.ndarray:
        """Best cosine of every asset (its best-matching row) per query: (n, n_assets), -inf for an asset
        without rows."""
        q = self._check_queries(queries)
        out = np.full((len(q), int(n_assets)), -np.inf, np.float32)
        if self.rows == 0 or not len(q):
            return out
        scores, ids = self.index.search(q, self.rows)
        full = np.empty_like(scores)
        np.put_along_axis(full, ids, scores, axis=1)  # back to row order
        out[:, self._start_asset] = np.maximum.reduceat(full[:, self._order], self._starts, axis=1)
        return out

    def _check_queries(self, queries: np.ndarray) -> np.ndarray:
        q = np.ascontiguousarray(queries, dtype=np.float32)
        if q.ndim == 1:
            q = q[None]
        if q.ndim != 2 or q.shape[1] != self.dim:
            raise LibraryError(
                f"query vectors have shape {q.shape} but the library index has dimension {self.dim}: "
                "they were made by another embedder; query with the library's own embedder"
            )
        return q

    def save(self, path: str | Path) -> str:
        """Write the FAISS index atomically; return its SHA-256 (recorded in library.json)."""
        import faiss

        path = Path(path)
        with atomic_path(path, suffix=".faiss") as tmp:
            faiss.write_index(self.index, str(tmp))
            digest = hashlib.sha256(tmp.read_bytes()).hexdigest()
        return digest

    @classmethod
    def load(cls, path: str | Path, row_asset: Sequence[int], dim: int, sha256: str | None = None) -> VectorIndex:
        import faiss

        path = Path(path)
        if not path.is_file():
            raise LibraryError(f"library index {path} is missing; rebuild the library (coastforge library build)")
        data = path.read_bytes()
        if sha256 and hashlib.sha256(data).hexdigest() != sha256:
            raise LibraryError(f"library index {path} does not match the hash in library.json (corrupted or "
                               "replaced); rebuild the library")
        try:
            index = faiss.read_index(str(path))
        except Exception as exc:  # faiss raises RuntimeError with C++ text
            raise LibraryError(f"library index {path} is unreadable ({exc}); rebuild the library") from exc
        if index.d != dim or index.ntotal != len(row_asset):
            raise LibraryError(
                f"library index {path} has {index.ntotal} rows of dimension {index.d}, but library.json expects "
                f"{len(row_asset)} rows of dimension {dim}; rebuild the library"
            )
        vectors = index.reconstruct_n(0, index.ntotal) if index.ntotal else np.zeros((0, dim), np.float32)
        return cls(vectors, row_asset)
