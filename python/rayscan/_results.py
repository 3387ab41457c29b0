"""Batch query results in CSR layout (as scipy.sparse.csr_matrix rows): query i's results are
the slice offsets[i]:offsets[i+1] of each flat array, ranked best first."""

import operator

import numpy as np


class _CsrResult:
    __slots__ = ("offsets", "indices")
    _fields = ("indices",)

    def __init__(self, **arrays):
        for name, value in arrays.items():
            setattr(self, name, value)

    def __len__(self):
        """Number of queries (rays, points, boxes)."""
        return len(self.offsets) - 1

    @property
    def counts(self):
        """(M,) int64: number of results of each query."""
        return np.diff(self.offsets)

    def __getitem__(self, i):
        """Original point indices of query i's results, ranked: an integer in [-M, M), negative
        counting from the end as in a list. Raises IndexError outside that range, TypeError for
        another type."""
        try:
            i = operator.index(i)
        except TypeError:
            raise TypeError(f"query index must be an integer, got {type(i).__name__}") from None
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"query index {i} is out of range for {n} queries")
        if i < 0:
            i += n
        return self.indices[self.offsets[i]:self.offsets[i + 1]]

    def first(self, field="indices", fill=None):
        """(M,) array: `field` of each query's best result; queries without a result get `fill`
        (default -1 for indices, NaN for floats). `field` is one of the result's fields
        ("index", the CLI's column name, means "indices"); another name raises ValueError."""
        if field == "index":
            field = "indices"
        if field not in self._fields:
            raise ValueError(f"first: field {field!r} is not one of {', '.join(self._fields)}")
        a = getattr(self, field)
        if fill is None:
            fill = -1 if a.dtype.kind in "iu" else np.nan
        out = np.full(len(self), fill, dtype=np.result_type(a.dtype, np.min_scalar_type(fill)))
        has = self.offsets[1:] > self.offsets[:-1]
        out[has] = a[self.offsets[:-1][has]]
        return out

    def __repr__(self):
        return (f"<rayscan.{type(self).__name__}: {len(self)} queries, {len(self.indices)} results; "
                f"fields offsets, {', '.join(self._fields)}>")


class RayQueryResult(_CsrResult):
    """Result of ray_query for M rays:
    offsets (M+1,) int64, indices (H,) int64 original point indices, t (H,) float64 ray parameter
    (projection t_p for orders 'ray'/'time', sphere entry for 'sphere_hit'; world units along the
    unit direction), distance (H,) float64 orthogonal distance to the ray line (not squared)."""
    __slots__ = ("t", "distance")
    _fields = ("indices", "t", "distance")


class NeighborResult(_CsrResult):
    """Result of knn / radius for Q query points: offsets (Q+1,) int64, indices (H,) int64,
    distance (H,) float64 Euclidean distance (not squared), sorted by (distance, index)."""
    __slots__ = ("distance",)
    _fields = ("indices", "distance")


class BoxResult(_CsrResult):
    """Result of box for B boxes: offsets (B+1,) int64, indices (H,) int64 (index storage order)."""
    __slots__ = ()
