"""Inside and outside of a closed cloud: the side of every patch chosen by the winding number.

A consistent orientation propagated along a neighbour graph (the spanning tree
of :mod:`heatcurv.orient.orientation`) is only locally right: where the two sides of
a part are closer than the neighbourhood (a leg, an ear, a tail), one wrong
edge turns a whole part inside out, and nothing local reveals it. The
generalised winding number (:mod:`heatcurv._kernels.winding`) is global: for a
closed surface oriented outward it is about 1 just inside and 0 just outside;
inside a part turned inside out it is about -1, and next to it (outside or
inside) out of ``[0, 1]``. This module uses that field three times.

1. **Patch signs.** The spanning tree is cut into patches (its subtrees inside
   the cells of a grid, small pieces merged into a neighbour): orientation is
   consistent inside a patch, and each patch ``r`` gets a sign ``s_r``. At
   every source point ``i`` (area ``A_i``, patch ``r_i``) two queries sit at
   ``x_i +- delta_i n_i``; with the signs ``s`` the field there is
   ``sum_r s_r W_r(q)`` (``W_r``: the field of patch ``r`` as oriented by the
   tree) and should be 0 on the side the flipped normal ``s_{r_i} n_i`` points
   to and 1 on the other. Both targets are linear in ``s``
   (``1/2 -+ s_{r_i}/2``), so the signs minimise one least-squares energy
   ``sum_i A_i [(f(q_i^+) - 1/2 + s_{r_i}/2)^2 + (f(q_i^-) - 1/2 - s_{r_i}/2)^2]``,
   in the spirit of Xu et al. 2023 ("Globally consistent normal orientation
   for point clouds by regularizing the winding-number field"). It is solved
   relaxed (real ``s``, normal equations), rounded to signs, then improved by
   single-patch flips while any lowers it, turning a patch away from the tree's
   side only for a clear gain (``TUNING.flip_margin``). Tree edges across which
   the normals or the tangent planes disagree (``TUNING.sure_cost``) do not join
   a patch.
2. **Levels.** With the chosen signs, a point whose outside query is not near
   0 or whose inside query is not near 1 (``TUNING.level_tolerance``) has no
   side the field supports: a part too thin for ``delta`` (the inside query
   leaves it), a normal whose direction is wrong (its ball wraps around a thin
   part), a patch that straddles both sides. Such points are flagged, and so
   is a point whose disc (below) holds more than ``TUNING.spread_share`` of
   flagged points: a small spot turned inside out amid right ones has levels
   that agree (the field of a hole in a closed surface is 1/2 on both sides,
   and the spot's own disc adds the jump), its neighbours' do not. A patch
   has one side, so when more than ``TUNING.patch_share`` of its area is
   flagged, all of it is.
3. **Finer pieces.** Where the tree crossed between the two sides of a thin
   part inside a patch, no sign of the patch is right. A closed cloud's
   patches with more than ``TUNING.refine_share`` of their area flagged are
   cut again into pieces of a quarter of their size (:func:`patches`),
   and the energy is solved once more over those pieces and the other
   patches, with the first solve's sides as the tree's; a source is flagged
   when either solve contradicts it.
4. **A second opinion.** The winding field's own normals, solved over the
   sources from no orientation at all (:mod:`heatcurv.orient.consistency`),
   flag a source whose chosen normal points against them
   (``TUNING.field_agreement``), and so do the sheets the chosen sides
   split along a seam (:func:`heatcurv.orient.consistency.split_sheets`):
   surfaces passing through each other, whose parts inside each other the
   field turns over.

Each query's value is summed over point dipoles (Barill et al. 2018, "Fast
winding numbers for soups and clouds"), except near its own point: the sources
around ``x_i`` in its tangent plane count as one flat disc of their area,
whose solid angle on its axis is exact, and no other source counts for more
than a disc of its own area would (:func:`heatcurv._kernels.winding.winding_numbers`),
so that neither the sampling next to a query nor noise decides its value.

A cloud is taken to enclose a volume when the levels are close to their
targets on enough of it (``TUNING.closed_share``, ``TUNING.closed_tolerance``); an
open sheet's field is about ``-+1/2`` on its two sides (between 0 and 1/2 on
both sides of one curved like a bowl), so open clouds keep the tree's
orientation untouched. A cloud whose share lies between ``TUNING.undecided_share``
and ``TUNING.closed_share`` while its outside levels are near 0 on most of it
(``TUNING.outside_share``: its normals point out of something; an open scene's
field is about ``-1/2`` on one side of its sheets) is an object too coarse
for its levels to be sure (legs a few spacings thick): it is *undecided*;
its patches take the field's sides, which are right more often than the
tree's there, and every point is flagged, since no side can be vouched for.
Below ``TUNING.undecided_share`` too when the sources' balls are round
(median PCA roundness ``TUNING.coarse_roundness`` or more: they wrap around
legs), where an open scan's are flat.

The sums are exact over at most :data:`MAX_SOURCES` source points (all of a
smaller cloud; above that, a subsample chosen by the coordinates alone, its
areas scaled to the whole). In a larger cloud a point is flagged when most of
the sources in its ball are.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.linalg.blas import dsyrk
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from .._kernels.graph import merged_components, undirected_edges
from .._kernels.winding import clipped_dipole_terms, winding_numbers
from ..errors import HeatcurvWarning
from ..geometry.neighbourhood import Neighbourhood
from ..geometry.validation import row_hashes
from ..tuning import TUNING
from .consistency import field_normals, noise_scatter, object_groups, split_sheets

__all__ = [
    "Enclosure", "PatchSides", "enclose", "patch_sides", "patches", "sampled_sources", "source_keys", "upward_sides",
    "vertical_sums", "source_roundness", "MAX_SOURCES", "MAX_UNKNOWNS", "warn_undecided",
]

#: Most points the winding sums run over (each is a source and carries two queries).
MAX_SOURCES = 6000
#: Fewest sources the winding number judges a cloud, or one object of a cloud, by.
FEWEST_SOURCES = 16
#: Nearest sources each source is joined to in the graph whose components are a cloud's objects.
OBJECT_NEIGHBOURS = 8
#: Fewest points a patch aims at, and the most patches a cloud is cut into.
PATCH_POINTS, MAX_PATCHES = 30, 300
#: Most unknowns of the solve over re-cut patches: its two fields hold 2 x 6000 x 3000 x 8 bytes (288 MB).
MAX_UNKNOWNS = 3000
#: A query sits this fraction of its tangent-plane disc's radius off the surface.
QUERY_OFFSET = 0.5
#: Neighbours a query's tangent-plane disc is made of.
DISC_NEIGHBOURS = 16
#: Most a query's offset takes of the depth of the nearest neighbour off the tangent plane.
ACROSS = 0.5


@dataclass(frozen=True)
class Enclosure:
    """The winding-number orientation of a cloud.

    Attributes
    ----------
    normals : ndarray, shape (n, 3)
        The normals, each patch flipped where the field says so (unchanged
        when neither ``closed`` nor ``undecided``).
    unsupported : ndarray, shape (n,), bool
        Points whose side the field contradicts (all False when not
        ``closed``; every point not excluded when ``undecided``).
    closed : bool
        Whether the levels agree on at least ``TUNING.closed_share`` of the area.
    agreement : float
        That share, in ``[0, 1]``.
    flipped : int
        Points whose normal the patch signs turned over.
    undecided : bool
        Neither closed nor open for sure (:class:`PatchSides`).
    outside_share : float
        Share of the area whose outside level is near 0 (:class:`PatchSides`).
    sources : ndarray, shape (n,), bool or None
        The points the winding sums ran over; None unless ``closed`` or ``undecided``.
    open : ndarray, shape (n,), bool or None
        With ``sources``: the points of objects open on their own
        (:func:`patch_sides`), which keep the tree's sides and are never
        ``unsupported``; None when there are none.
    open_components : int
        How many such objects.
    upward : ndarray, shape (n,), bool or None
        The points of the objects open on their own (or, on an open cloud, of
        any object) that lie over the horizontal plane and were made to face
        ``+z`` (``open_up``); None when there are none.
    upward_components : int
        How many such objects.
    """

    normals: np.ndarray
    unsupported: np.ndarray
    closed: bool
    agreement: float
    flipped: int
    undecided: bool = False
    outside_share: float = 0.0
    sources: np.ndarray | None = None
    open: np.ndarray | None = None
    open_components: int = 0
    upward: np.ndarray | None = None
    upward_components: int = 0


def enclose(points: np.ndarray, normals: np.ndarray, forest: sp.csr_matrix, areas: np.ndarray,
            neighbourhood: Neighbourhood, excluded: np.ndarray | None = None,
            roundness: np.ndarray | None = None, open_up: bool = False) -> Enclosure:
    """Choose the side of every patch of the spanning forest by the winding number, and flag what it contradicts.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    normals : ndarray, shape (n, 3)
        Unit normals, consistent along every edge of ``forest``.
    forest : scipy.sparse.csr_matrix, shape (n, n)
        The symmetric spanning forest the normals were propagated over, its
        entries the edges' costs.
    areas : ndarray, shape (n,)
        Per-point areas (the dipoles' strengths).
    neighbourhood : Neighbourhood
        The points' balls: in a sampled cloud, a point is flagged when most
        of the sources in its ball are.
    excluded : ndarray, shape (n,), bool, optional
        Points that are neither sources nor flagged (outliers).
    roundness : ndarray, shape (n,), optional
        The balls' PCA roundness ``lambda_0 / lambda_1``: a cloud whose
        sources' balls are round is coarse (:func:`patch_sides`).
    open_up : bool, optional
        Whether objects open on their own, or the objects of an open cloud, that
        lie over the horizontal plane face ``+z`` instead of keeping the tree's
        sides (:func:`patch_sides`).

    Returns
    -------
    Enclosure
    """
    n = points.shape[0]
    excluded = np.zeros(n, dtype=bool) if excluded is None else np.asarray(excluded, dtype=bool)
    nothing = Enclosure(normals, np.zeros(n, dtype=bool), False, 0.0, 0)
    if n - excluded.sum() < 16:
        return nothing
    patch, fine = patches(points, forest, excluded)
    source = _sources(points, patch, excluded)
    weight = np.abs(areas[source]) * (np.abs(areas[~excluded]).sum() / np.abs(areas[source]).sum())
    n_patch = int(patch.max()) + 1
    sides = patch_sides(points[source], normals[source], weight, patch[source], n_patch,
                        fine[source], int(fine.max()) + 1, None if roundness is None else roundness[source],
                        open_up=open_up)
    upward = sides.upward_patches(patch[source], n_patch)[patch] & ~excluded if sides.upward_components else None
    if not (sides.closed or sides.undecided):  # open: the tree's sides, or up for the objects over the ground
        open_cloud = Enclosure(normals, np.zeros(n, dtype=bool), False, sides.agreement, 0,
                               outside_share=sides.outside_share)
        if upward is None:
            return open_cloud
        return dataclasses.replace(
            open_cloud, normals=np.where((upward & (sides.sign[patch] < 0))[:, None], -normals, normals),
            upward=upward, upward_components=sides.upward_components)
    flip = sides.sign[patch] * sides.fine_sign[fine] < 0
    flip[excluded] = False
    is_open = None
    if sides.open_components:
        is_open = sides.open_patches(patch[source], n_patch)[patch] & ~excluded
    unsupported = (~excluded if is_open is None else ~excluded & ~is_open) if sides.undecided else \
        _unsupported(source, sides.bad, neighbourhood, excluded)
    oriented = np.where(flip[:, None], -normals, normals)
    is_source = np.zeros(n, dtype=bool)
    is_source[source] = True
    turned = flip if is_open is None else flip & ~is_open  # an open object turned up is not the field's doing
    return Enclosure(oriented, unsupported, sides.closed, sides.agreement, int(turned.sum()), sides.undecided,
                     sides.outside_share, is_source, is_open, sides.open_components, upward, sides.upward_components)


@dataclass(frozen=True)
class PatchSides:
    """The winding number's verdict on a sample of sources (:func:`patch_sides`).

    Attributes
    ----------
    sign : ndarray, shape (n_patch,)
        ``+1`` to keep each patch's normals, ``-1`` to flip them.
    bad : ndarray, shape (m,), bool
        Sources whose levels (with those signs) contradict their side, whose
        disc holds more than ``TUNING.spread_share`` of such sources, or whose
        patch has more than ``TUNING.patch_share`` of its weight in them.
    agreement : float
        Share of the sources' weight whose levels are within
        ``TUNING.closed_tolerance`` of their targets.
    closed : bool
        ``agreement >= TUNING.closed_share``: the sources enclose a volume.
    undecided : bool
        ``agreement < TUNING.closed_share`` and ``outside_share >= TUNING.outside_share``,
        with ``agreement >= TUNING.undecided_share`` or the sources' balls round
        (median roundness at least ``TUNING.coarse_roundness``: a coarse object): they may
        or may not.
    outside_share : float
        Share of the sources' weight whose outside level is within
        ``TUNING.closed_tolerance`` of 0.
    fine_sign : ndarray, shape (n_fine,), optional
        With finer patches: ``+1`` or ``-1`` for each, on top of its patch's
        ``sign`` (all ``+1`` where no patch was re-cut).
    sure : ndarray, shape (m,), bool, optional
        Sources whose levels are within ``TUNING.closed_tolerance`` of their targets
        (those ``agreement`` counts).
    open : ndarray, shape (m,), bool, optional
        Sources of objects that are open on their own (:func:`patch_sides`): their
        patches keep the tree's sides (or face up, below), and none of them is ``bad``.
        The verdict above is that of the other sources.
    open_components : int
        How many such objects.
    upward : ndarray, shape (m,), bool, optional
        With ``open_up``: the sources of the objects open on their own (or,
        neither ``closed`` nor ``undecided``, of any object) over the horizontal
        plane (:func:`upward_sides`), whose patches' ``sign`` makes them face
        ``+z``; an open cloud's other patches then have ``sign`` 1.
    upward_components : int
        How many such objects.
    """

    sign: np.ndarray
    bad: np.ndarray
    agreement: float
    closed: bool
    undecided: bool = False
    outside_share: float = 0.0
    fine_sign: np.ndarray | None = None
    sure: np.ndarray | None = None
    open: np.ndarray | None = None
    open_components: int = 0
    upward: np.ndarray | None = None
    upward_components: int = 0

    def open_patches(self, label: np.ndarray, n_patch: int) -> np.ndarray:
        """The patches of :attr:`open` sources (``label``: the sources' patches), shape (n_patch,), bool."""
        return _patches_of(self.open, label, n_patch)

    def upward_patches(self, label: np.ndarray, n_patch: int) -> np.ndarray:
        """The patches of :attr:`upward` sources (``label``: the sources' patches), shape (n_patch,), bool."""
        return _patches_of(self.upward, label, n_patch)


def _patches_of(sources: np.ndarray | None, label: np.ndarray, n_patch: int) -> np.ndarray:
    """The patches holding any of ``sources`` (a mask over ``label``, or None: none), shape (n_patch,), bool."""
    out = np.zeros(n_patch, dtype=bool)
    if sources is not None:
        out[label[sources]] = True
    return out


def patch_sides(x: np.ndarray, nrm: np.ndarray, weight: np.ndarray, label: np.ndarray, n_patch: int,
                fine: np.ndarray | None = None, n_fine: int = 0, roundness: np.ndarray | None = None,
                objects: bool = True, open_up: bool = False) -> PatchSides:
    """Each patch's side and each source's verdict, from the winding number of the sources (module docstring).

    With finer patches (:func:`patches`' pieces), a closed cloud's patches of
    which more than ``TUNING.refine_share`` of the area disagrees are re-cut
    into them (the most contradicted first, within :data:`MAX_UNKNOWNS`
    unknowns) and the energy is solved again, the other patches as they are,
    every normal turned by the first solve's signs: where the spanning tree
    crossed between the two sides of a thin part inside a patch, one sign
    for the patch cannot be right, one for each of its pieces can. A source
    is flagged when either solve contradicts it.

    A cloud of several objects is judged per object as well (``objects``):
    the objects are the connected components of the sources' graph
    (:func:`source_objects`), so that a run in tiles finds the same ones as
    in memory. An object of at least :data:`FEWEST_SOURCES` sources whose
    levels agree on less than ``TUNING.closed_share`` of it in the solve
    over all sources, and which on its own is neither closed nor undecided
    (an open sheet beside a closed object, whose field of about ``-+1/2``
    contradicts the object's levels and its own), is open: its patches keep
    the tree's sides, none of its sources is flagged, and the others are
    solved again without it. Objects that agree stay together, so that the
    field still sees a cavity inside an object and an object sampled in pieces.
    With ``open_up`` (``orient="auto"``), an object open on its own, or any
    object of an open cloud, that lies over the horizontal plane
    (:func:`upward_sides`: the ground beside a boulder, terrain around a
    building) faces ``+z``, as the same object alone would (:mod:`heatcurv.orient.auto`).

    A closed cloud's sources then get a second opinion that shares nothing with
    the spanning tree: the winding field's own normals, solved from no
    orientation (:func:`heatcurv.orient.consistency.field_normals`, over the
    sources not open). A source whose chosen normal makes a cosine below
    ``TUNING.field_agreement`` with the field's is flagged too: where two
    methods disagree about a side, neither is vouched for. So is a source
    whose side contradicts the continuation of its smooth sheet
    (:func:`heatcurv.orient.consistency.split_sheets`), where surfaces pass
    through each other.

    Parameters
    ----------
    x, nrm : ndarray, shape (m, 3)
        The sources and their unit normals, consistent inside every patch.
    weight : ndarray, shape (m,)
        Their areas, scaled so that they sum to the whole cloud's area.
    label : ndarray, shape (m,), int
        Their patches, ``0 <= label < n_patch`` (a patch without sources keeps its side).
    n_patch : int
    fine : ndarray, shape (m,), int, optional
        Their finer patches, ``0 <= fine < n_fine``, each inside one patch.
    n_fine : int, optional
    roundness : ndarray, shape (m,), optional
        The PCA roundness of their balls (NaN or None when unknown): a cloud
        whose median (:func:`source_roundness`) is ``TUNING.coarse_roundness``
        or more is coarse, and undecided below ``TUNING.undecided_share`` too.
    objects : bool, optional
        Whether to judge each object on its own too (the solve over the other objects does not).
    open_up : bool, optional
        Whether the open objects over the horizontal plane face ``+z`` (else they keep the tree's sides).
        On an open cloud, only then is ``sign`` meant to be applied (:attr:`PatchSides.upward`).

    Returns
    -------
    PatchSides
    """
    sides = _winding_sides(x, nrm, weight, label, n_patch, fine, n_fine, roundness, objects, open_up)
    if not sides.closed:
        if open_up and not sides.undecided:  # an open cloud: each of its objects as it would be alone
            every = np.ones(x.shape[0], dtype=bool)
            return _turned_up(sides, source_objects(x, label), nrm, weight, label, roundness, every)
        return sides
    # a second opinion from no orientation at all: the winding field's own normals
    own = nrm * (sides.sign[label] * (1.0 if fine is None else sides.fine_sign[fine]))[:, None]
    judged = np.flatnonzero(np.ones(x.shape[0], dtype=bool) if sides.open is None else ~sides.open)
    doubt = np.zeros(x.shape[0], dtype=bool)
    if judged.size >= FEWEST_SOURCES:
        # the field's widths are fractions of the box it is solved in: each group of nearby objects in its own
        group = object_groups(x[judged], source_objects(x[judged], label[judged]))
        for members in np.split(judged[np.argsort(group, kind="stable")], np.cumsum(np.bincount(group))[:-1]):
            if members.size >= FEWEST_SOURCES:
                field = field_normals(x[members], axes=own[members])
                doubt[members] = np.einsum("ij,ij->i", own[members], field) < TUNING.field_agreement
        doubt[judged] |= split_sheets(x[judged], own[judged], weight[judged])
    return dataclasses.replace(sides, bad=sides.bad | doubt)


def _winding_sides(x, nrm, weight, label, n_patch, fine, n_fine, roundness, objects, open_up=False) -> PatchSides:
    """:func:`patch_sides` from the winding energy alone, without the field's own normals."""
    sides = _solved_sides(x, nrm, weight, label, n_patch, source_roundness(roundness))
    fine_sign = np.ones(n_fine)
    if objects:
        is_open, owner = _open_objects(x, nrm, weight, label, roundness, sides.sure)
        if is_open.any():
            inner = _without(is_open, owner, x, nrm, weight, label, n_patch, fine, n_fine, roundness, sides)
            if open_up and (inner.closed or inner.undecided):
                return _turned_up(inner, owner, nrm, weight, label, roundness, inner.open)
            return inner
    if fine is None or not sides.closed:
        return dataclasses.replace(sides, fine_sign=fine_sign)
    share = np.bincount(label, weights=weight * sides.bad, minlength=n_patch) / np.maximum(
        np.bincount(label, weights=weight, minlength=n_patch), np.finfo(float).tiny)
    recut = _recut(share, label, fine, n_patch)
    if not recut.any():
        return dataclasses.replace(sides, fine_sign=fine_sign)
    # the re-cut patches' pieces are unknowns of their own, after the others
    pieces, piece = np.unique(fine[recut[label]], return_inverse=True)
    combined = label.copy()
    combined[recut[label]] = n_patch + piece
    turned = nrm * sides.sign[label][:, None]
    again = _solved_sides(x, turned, weight, combined, n_patch + pieces.size)
    if not again.closed:
        return dataclasses.replace(sides, fine_sign=fine_sign)
    fine_sign[pieces] = again.sign[n_patch:]
    sign = sides.sign * np.where(recut, 1.0, again.sign[:n_patch])
    return dataclasses.replace(sides, sign=sign, bad=sides.bad | again.bad, fine_sign=fine_sign)


def _recut(share: np.ndarray, label: np.ndarray, fine: np.ndarray, n_patch: int) -> np.ndarray:
    """The patches to re-cut, shape (n_patch,), bool: over ``TUNING.refine_share`` contradicted, the most first.

    The second solve's unknowns (the patches plus the pieces of the re-cut
    ones) stay within :data:`MAX_UNKNOWNS`.
    """
    candidates = np.flatnonzero(share > TUNING.refine_share)
    pairs = np.unique(np.column_stack([label, fine]), axis=0)
    pieces = np.bincount(pairs[:, 0], minlength=n_patch)[candidates]
    order = np.argsort(-share[candidates], kind="stable")
    fits = np.cumsum(pieces[order]) <= MAX_UNKNOWNS - n_patch
    recut = np.zeros(n_patch, dtype=bool)
    recut[candidates[order[fits]]] = True
    return recut


def _solved_sides(x: np.ndarray, nrm: np.ndarray, weight: np.ndarray, label: np.ndarray, n_patch: int,
                  roundness: float = float("nan")) -> PatchSides:
    """One solve of the winding energy over the patches ``label`` (:func:`patch_sides`, without re-cutting)."""
    along, against, (disc_rows, disc_members) = patch_fields(x, nrm, weight, label, n_patch)
    G, c = _energy(along, against, label, weight)
    sign = _patch_signs(G, c, label, weight)

    # the levels with the chosen signs: outside is along the flipped normal
    own = sign[label]
    field_along, field_against = along @ sign, against @ sign
    outside = np.where(own > 0, field_along, field_against)
    inside = np.where(own > 0, field_against, field_along)
    agrees = (np.abs(outside) <= TUNING.level_tolerance) & (np.abs(inside - 1.0) <= TUNING.level_tolerance)
    sure = (np.abs(outside) <= TUNING.closed_tolerance) & (np.abs(inside - 1.0) <= TUNING.closed_tolerance)
    agreement = float(weight[sure].sum() / weight.sum())
    outside_share = float(weight[np.abs(outside) <= TUNING.closed_tolerance].sum() / weight.sum())
    # a source disagrees when its levels do, or many of its disc's do (a flipped spot's own levels agree)
    bad = ~agrees
    share = np.bincount(disc_rows, weights=bad[disc_members], minlength=bad.size) / np.bincount(
        disc_rows, minlength=bad.size)
    bad |= share > TUNING.spread_share
    # a patch has one side: where much of it disagrees, that side is in doubt at its agreeing points too
    patch_bad = np.bincount(label, weights=weight * bad, minlength=n_patch)
    bad |= patch_bad[label] > TUNING.patch_share * np.bincount(label, weights=weight, minlength=n_patch)[label]
    # a coarse object's levels can agree on almost none of it; an open scene's balls are flat
    unsure = agreement >= TUNING.undecided_share or roundness >= TUNING.coarse_roundness
    undecided = unsure and agreement < TUNING.closed_share and outside_share >= TUNING.outside_share
    return PatchSides(sign, bad, agreement, agreement >= TUNING.closed_share, undecided, outside_share, sure=sure)


def source_objects(x: np.ndarray, label: np.ndarray) -> np.ndarray:
    """The object of every source, shape (m,), int: connected components of its :data:`OBJECT_NEIGHBOURS`
    nearest sources and of its patch (``label``), so that a patch lies in one object."""
    m = x.shape[0]
    k = min(OBJECT_NEIGHBOURS, m - 1)
    if k < 1:
        return np.zeros(m, dtype=np.int64)
    nearest = cKDTree(x).query(x, k + 1)[1][:, 1:].ravel()
    first = np.unique(label, return_index=True)[1]
    patch_first = first[np.searchsorted(np.unique(label), label)]
    rows = np.concatenate([np.repeat(np.arange(m), k), np.arange(m)])
    graph = sp.csr_matrix((np.ones(rows.size), (rows, np.concatenate([nearest, patch_first]))), shape=(m, m))
    return csgraph.connected_components(graph, directed=False)[1]


def _open_objects(x, nrm, weight, label, roundness, sure) -> tuple[np.ndarray, np.ndarray]:
    """The sources of objects open on their own (:func:`patch_sides`), shape (m,), bool, and every source's
    object (:func:`source_objects`, numbered from 0), shape (m,), int."""
    is_open = np.zeros(x.shape[0], dtype=bool)
    _, inverse, counts = np.unique(source_objects(x, label), return_inverse=True, return_counts=True)
    judged = counts >= FEWEST_SOURCES
    if np.count_nonzero(judged) < 2:
        return is_open, inverse
    agreeing = np.bincount(inverse, weights=weight * sure) / np.bincount(inverse, weights=weight)
    for c in np.flatnonzero(judged & (agreeing < TUNING.closed_share)):  # one solve per object, not per point
        members = inverse == c
        own, own_label = np.unique(label[members], return_inverse=True)
        alone = _solved_sides(x[members], nrm[members], weight[members], own_label, own.size,
                              source_roundness(None if roundness is None else roundness[members]))
        is_open[members] = not (alone.closed or alone.undecided)
    return is_open, inverse


def _without(is_open, owner, x, nrm, weight, label, n_patch, fine, n_fine, roundness, sides) -> PatchSides:
    """:func:`patch_sides` over the sources not ``is_open`` (their objects: ``owner``), whose patches keep their
    sides (all, when too few are left)."""
    count = int(np.unique(owner[is_open]).size)
    rest = ~is_open
    if np.count_nonzero(rest) < FEWEST_SOURCES:
        return PatchSides(np.ones(n_patch), np.zeros(x.shape[0], dtype=bool), sides.agreement, False, False,
                          sides.outside_share, np.ones(n_fine), sides.sure, is_open, count)
    inner = _winding_sides(x[rest], nrm[rest], weight[rest], label[rest], n_patch,
                           None if fine is None else fine[rest], n_fine,
                           None if roundness is None else roundness[rest], objects=False)
    bad, sure = np.zeros(x.shape[0], dtype=bool), np.zeros(x.shape[0], dtype=bool)
    bad[rest], sure[rest] = inner.bad, inner.sure
    return dataclasses.replace(inner, bad=bad, sure=sure, open=is_open, open_components=count)


def _turned_up(sides: PatchSides, owner, nrm, weight, label, roundness, judged) -> PatchSides:
    """``sides`` with the ``judged`` sources' objects (``owner``) that lie over the horizontal plane
    (:func:`upward_sides`) facing ``+z``.

    On a closed or undecided cloud the judged objects are those open on their
    own and the other patches keep the winding number's signs; on an open
    cloud every object is judged and the others keep the tree's sides.
    """
    flat = np.ones(owner.size, dtype=bool) if roundness is None else ~(
        np.asarray(roundness, dtype=float) > TUNING.auto_flatness)
    side = upward_sides(nrm[:, 2], np.where(judged, weight, 0.0), flat, owner, int(owner.max()) + 1)
    upward = side[owner] != 0
    count = int(np.count_nonzero(side))
    if not count:
        return sides
    sign = sides.sign.copy() if sides.closed or sides.undecided else np.ones_like(sides.sign)
    sign[label[upward]] = side[owner[upward]]  # an object's patches hold no other object's sources
    return dataclasses.replace(sides, sign=sign, upward=upward, upward_components=count)


def upward_sides(nz: np.ndarray, weight: np.ndarray, flat: np.ndarray, labels: np.ndarray,
                 n_labels: int) -> np.ndarray:
    """For each object, the sign that makes it face ``+z`` if it lies over the horizontal plane, else 0.

    The test of :func:`heatcurv.orient.auto.auto_policy` along ``z``, on each
    object's own consistently oriented normals: at least ``TUNING.auto_share``
    of its weight within 45 degrees of vertical, and at most
    ``TUNING.auto_down_share`` of ``sum |n_z|`` over its flat normals that are
    not walls (``|n_z| >= TUNING.auto_wall_cosine``) on the side that faces
    the other way. Not the sample's least flat share
    (``TUNING.auto_flat_share``): the sources' balls hold the operator's
    neighbours, narrower than the sample's, and noise of half their spacing
    leaves 2 % of a valley's flat where the sample's keep 80 %; the cloud's
    own test has read that share already.

    Parameters
    ----------
    nz : ndarray, shape (m,)
        The vertical components of the unit normals, consistent along each object.
    weight : ndarray, shape (m,)
        Their areas (0: not counted).
    flat : ndarray, shape (m,), bool
        Normals whose balls are flat (``lambda_0 / lambda_1`` at most ``TUNING.auto_flatness``).
    labels : ndarray, shape (m,), int
        Each normal's object, ``0 <= labels < n_labels``.
    n_labels : int

    Returns
    -------
    ndarray, shape (n_labels,)
        ``+1`` (it faces up already), ``-1`` (turn it over) or ``0`` (not over the horizontal plane).
    """
    def total(values):
        return np.bincount(labels, weights=values, minlength=n_labels)

    steep = total(weight * (np.abs(nz) >= TUNING.auto_vertical_cosine)) >= TUNING.auto_share * total(weight)
    upward, downward = vertical_sums(nz, weight, flat, labels, n_labels)
    one_side = np.minimum(upward, downward) <= TUNING.auto_down_share * (upward + downward)
    over = steep & one_side & (upward + downward > 0.0)
    return np.where(over, np.where(upward >= downward, 1.0, -1.0), 0.0)


def vertical_sums(nz: np.ndarray, weight: np.ndarray, flat: np.ndarray, labels: np.ndarray,
                  n_labels: int) -> tuple[np.ndarray, np.ndarray]:
    """Per object, ``sum w n_z`` over its flat normals facing up and ``sum w |n_z|`` over those facing down.

    Only the normals that are not walls (``|n_z| >= TUNING.auto_wall_cosine``)
    count: a wall's ``n_z`` is noise. The smaller of the two sums is what
    faces the other way on a surface over the horizontal plane.

    Parameters are those of :func:`upward_sides`.

    Returns
    -------
    upward, downward : ndarray, shape (n_labels,)
    """
    counted = weight * (flat & (np.abs(nz) >= TUNING.auto_wall_cosine))
    upward = np.bincount(labels, weights=counted * np.clip(nz, 0.0, None), minlength=n_labels)
    downward = np.bincount(labels, weights=counted * np.clip(-nz, 0.0, None), minlength=n_labels)
    return upward, downward


def source_roundness(roundness: np.ndarray | None, source=slice(None)) -> float:
    """The median PCA roundness of the sources' balls (:func:`patch_sides`), NaN when unknown."""
    if roundness is None:
        return float("nan")
    values = np.asarray(roundness, dtype=float)[source]
    values = values[np.isfinite(values)]
    return float(np.median(values)) if values.size else float("nan")


def warn_undecided(agreement: float, outside_share: float, stacklevel: int = 2) -> None:
    """Warn that the field cannot tell whether the cloud encloses a volume, so every side is flagged."""
    warnings.warn(
        f"cannot tell whether the cloud encloses a volume (the winding number agrees with its normals' sides on "
        f"{100 * agreement:.1f} % of its area, where closed objects reach {100 * TUNING.closed_share:.0f} %, "
        f"and is near 0 outside {100 * outside_share:.0f} % of it, where open scans stay below "
        f"{100 * TUNING.outside_share:.0f} %): every "
        "normal's side is flagged unreliable. A closed object sampled more densely decides it; pass orient='up' or "
        "a viewpoint for an open scan.", HeatcurvWarning, stacklevel=stacklevel + 1)


def _unsupported(source: np.ndarray, bad: np.ndarray, neighbourhood: Neighbourhood, excluded: np.ndarray):
    """The points flagged, shape (n,), bool: the disagreeing sources, and in a sampled cloud the others by their balls.

    A point that is not a source is flagged when more than half of the
    sources in its ball disagree (none when its ball holds no source). Only
    the rows of points near a disagreeing source are read.
    """
    n = excluded.shape[0]
    unsupported = np.zeros(n, dtype=bool)
    unsupported[source] = bad
    if source.size == n - excluded.sum() or not bad.any():
        return unsupported
    is_source = np.zeros(n, dtype=bool)
    is_source[source] = True
    # the points whose balls hold a disagreeing source: rows of the balls of those sources (balls are about symmetric)
    near = np.zeros(n, dtype=bool)
    flagged = source[bad]
    near[neighbourhood.take_rows(flagged).indices] = True
    near &= ~is_source & ~excluded
    rows = np.flatnonzero(near)
    balls = neighbourhood.take_rows(rows)
    slot = np.repeat(np.arange(rows.size), balls.counts)
    sources = np.bincount(slot, weights=is_source[balls.indices], minlength=rows.size)
    against = np.bincount(slot, weights=unsupported[balls.indices], minlength=rows.size)
    unsupported[rows] = against > TUNING.against_share * sources
    return unsupported


def patches(points: np.ndarray, forest: sp.csr_matrix, excluded: np.ndarray,
            cloud_points: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cut the spanning forest into patches, and each patch into finer pieces, two arrays of shape (n,).

    Patches are the forest's subtrees inside grid cells whose side is chosen
    for about ``max(PATCH_POINTS, N / MAX_PATCHES)`` points a cell, ``N`` the
    points not excluded, or ``cloud_points`` when ``points`` are a part (a
    tile) of a cloud of that many; a piece of fewer than a quarter of that
    joins the patch across one of its cut tree edges (in one pass over them),
    so every patch is a subtree and the orientation inside it is the tree's.
    Tree edges across which the normals or the tangent planes disagree join
    nothing, except that a piece of fewer than ``TUNING.tiny_patch`` points (a
    single point) joins a neighbour across any of its tree edges: noise leaves
    single points behind such edges, thousands on a noisy cloud of a million
    points, and each would be one more unknown of the energy.

    The pieces are cut alike inside each patch, in cells of half the side (a
    quarter of the points): what :func:`patch_sides` solves for where a
    patch's one side is contradicted. Excluded points get -1 in both.
    """
    n = points.shape[0]
    i, j, entry, length = undirected_edges(forest.indptr, forest.indices, excluded, points)
    sure = forest.data[entry] <= TUNING.sure_cost
    target = max(PATCH_POINTS, (n - excluded.sum() if cloud_points is None else cloud_points) / MAX_PATCHES)
    spacing = np.median(length) if length.size else 1.0
    # a point that only unsure edges reach (a noisy point whose normal disagrees with its neighbours')
    # cannot carry a side of its own: it joins a neighbour across its tree edge
    patch = _cut(points, excluded, i, j, sure, np.ones(i.size, dtype=bool), target, spacing)
    within = patch[i] == patch[j]
    return patch, _cut(points, excluded, i, j, sure & within, within, target / 4, spacing)


def _cut(points, excluded, i, j, sure, joinable, target: float, spacing: float) -> np.ndarray:
    """Components of the tree edges ``(i, j)`` that are ``sure`` and inside one grid cell, shape (n,).

    The cells hold about ``target`` points; a piece of fewer than a quarter
    of that joins a neighbour across a ``sure`` edge, one of fewer than
    ``TUNING.tiny_patch`` points across a ``joinable`` one. Labels are
    ``0..count-1``, excluded points -1.
    """
    n = points.shape[0]
    cell = _cell_ids(points, np.sqrt(target) * spacing)
    label = merged_components(n, i, j, (cell[i] == cell[j]) & sure, sure, int(target / 4))
    label = merged_components(n, i, j, label[i] == label[j], joinable, TUNING.tiny_patch)
    label[excluded] = -1
    used = np.unique(label[label >= 0])
    relabel = np.full(label.max() + 2, -1)
    relabel[used] = np.arange(used.size)
    return relabel[label]


def _cell_ids(points: np.ndarray, side: float) -> np.ndarray:
    """The grid cell of every point, as one integer, shape (n,)."""
    index = np.floor((points - points.min(axis=0)) / side).astype(np.int64)
    dims = index.max(axis=0) + 1
    return np.ravel_multi_index(index.T, dims) if np.prod(dims.astype(float)) < 2**62 else \
        np.unique(index, axis=0, return_inverse=True)[1].ravel()


def _sources(points: np.ndarray, patch: np.ndarray, excluded: np.ndarray) -> np.ndarray:
    """The points the sums run over: all, or :data:`MAX_SOURCES` chosen by coordinates plus one per patch."""
    kept = np.flatnonzero(~excluded)
    if kept.size <= MAX_SOURCES:
        return kept
    chosen = kept[np.argpartition(source_keys(points[kept]), MAX_SOURCES)[:MAX_SOURCES]]
    one_each = kept[np.unique(patch[kept], return_index=True)[1]]
    return np.union1d(chosen, one_each)


def source_keys(points: np.ndarray) -> np.ndarray:
    """A pseudo-random rank of every point from its coordinates alone, shape (n,), uint64.

    The same points rank alike whatever the row order and whichever part of
    the cloud holds them (a tile), so a sample of the lowest ranks is the same
    sample everywhere.
    """
    return row_hashes(points)


def sampled_sources(points: np.ndarray, excluded: np.ndarray, cloud_points: int) -> np.ndarray:
    """The points of a part of a cloud that are among the winding number's sources, shape (n,), bool.

    About :data:`MAX_SOURCES` of the ``cloud_points`` points of the whole cloud rank (:func:`source_keys`)
    this low (all of a smaller cloud), so each part (a tile) picks its share of one sample from its own
    points; excluded points never are.
    """
    if cloud_points <= MAX_SOURCES:
        return ~excluded
    return ~excluded & (source_keys(points) <= np.uint64((2**64 * MAX_SOURCES) // cloud_points))


def patch_fields(x: np.ndarray, nrm: np.ndarray, weight: np.ndarray, label: np.ndarray, n_patch: int):
    """Each patch's winding number at every source's two queries, two arrays of shape (m, n_patch).

    Source ``i``'s queries sit at ``x_i +- delta_i n_i``. Summed as point
    dipoles, the sources next to a query would dominate it and make its value
    depend on how the points happen to fall; so the sources near ``x_i`` in its
    tangent plane (among its :data:`DISC_NEIGHBOURS` nearest: within 30 degrees
    of the plane or within the noise's scatter of it, normals within 60
    degrees of ``n_i``, and ``i`` itself) are replaced by a flat disc of their
    total area ``A``, whose exact solid angle on its axis at height ``delta``
    is ``2 pi (1 - delta / sqrt(delta^2 + A / pi))``, shared among their
    patches by area. ``delta_i`` is :data:`QUERY_OFFSET` times the disc's
    radius, at most :data:`ACROSS` times the depth, below or above the
    tangent plane, of the nearest neighbour off it, whichever way it faces
    (the other side of a thin part, or a part close by, which the query must
    not reach; a neighbour in the plane is on the sheet), and at least
    the noise's scatter (:func:`heatcurv.orient.consistency.noise_scatter` of
    the heights of the nearest over the plane).

    Parameters
    ----------
    x, nrm : ndarray, shape (m, 3)
        The sources and their unit normals (oriented as the tree left them).
    weight : ndarray, shape (m,)
        Their areas.
    label : ndarray, shape (m,), int
        Their patches, ``0 <= label < n_patch``.
    n_patch : int

    Returns
    -------
    along, against : ndarray, shape (m, n_patch)
        Each patch's field at ``x_i + delta_i n_i`` and at ``x_i - delta_i n_i``.
    disc : (ndarray, ndarray)
        The discs' members as pairs: source ``disc[1][p]`` is in the disc of
        source ``disc[0][p]`` (each source is in its own).
    """
    m = x.shape[0]
    k = min(DISC_NEIGHBOURS, m - 1)
    dist, idx = cKDTree(x).query(x, k + 1)  # column 0: the source itself
    rel = x[idx] - x[:, None, :]
    height = np.abs(np.einsum("ijk,ik->ij", rel, nrm))
    # the scatter of the nearest heights: noise (a point off the plane by less is still on the sheet)
    scatter = noise_scatter(height[:, 1:])
    flat = height <= np.maximum(0.5 * dist, scatter[:, None])
    in_plane = flat & (np.einsum("ijk,ik->ij", nrm[idx], nrm) >= 0.5)
    in_plane[:, 0] = True
    # a neighbour in the plane facing the other way (across a seam between patches the tree turned apart)
    # is on the sheet: no disc member, its dipole points the other way, and no bound on the queries' offset
    off_plane = np.where(flat, np.inf, height).min(axis=1)
    disc_area = np.where(in_plane, weight[idx], 0.0).sum(axis=1)
    radius = np.sqrt(disc_area / np.pi)
    delta = np.maximum(np.minimum(QUERY_OFFSET * radius, ACROSS * off_plane), scatter)
    dipoles = nrm * weight[:, None]
    rows = np.repeat(np.arange(m), k + 1)[in_plane.ravel()]
    near = idx.ravel()[in_plane.ravel()]
    # a disc of sources without area (a tiled run's second-sheet points, area 0) stands for nothing
    share = np.divide(weight[near], disc_area[rows], out=np.zeros(near.shape), where=disc_area[rows] > 0)
    reach = np.sqrt(delta**2 + radius**2)
    cap = 0.5 * (1.0 - np.divide(delta, reach, out=np.ones_like(reach), where=reach > 0))  # solid angle / 4 pi
    fields = []
    for side in (1.0, -1.0):
        q = x + side * delta[:, None] * nrm
        field = winding_numbers(q, x, dipoles, label, n_patch)
        # the near sources as point dipoles out, the disc in (seen from its front: -cap; from behind: +cap)
        d = x[near] - q[rows]
        point = clipped_dipole_terms(d, dipoles[near])
        np.add.at(field, (rows, label[near]), -point - side * cap[rows] * share)
        fields.append(field)
    return fields[0], fields[1], (rows, near)


def _energy(along: np.ndarray, against: np.ndarray, label: np.ndarray, weight: np.ndarray):
    """The winding energy as ``s' G s - 2 c' s + const`` (module docstring): ``G``, shape (r, r), ``c``, shape (r,)."""
    rows = np.arange(label.size)
    A = np.concatenate([along, against])  # one row per query
    A[rows, label] += 0.5
    A[label.size + rows, label] -= 0.5
    w = np.concatenate([weight, weight])
    c = 0.5 * (A.T @ w)
    # G = A' diag(w) A = B' B with B = diag(sqrt(w)) A: the symmetric rank-k update forms one triangle, in
    # half a general product's work; B' (Fortran order, no copy) is the factor syrk multiplies by its transpose
    A *= np.sqrt(w)[:, None]
    upper = dsyrk(1.0, A.T, trans=0)
    G = np.triu(upper) + np.triu(upper, 1).T
    return G, c


def _patch_signs(G: np.ndarray, c: np.ndarray, label: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """The sign of every patch, shape (n_patch,): the winding energy's minimum, kept near the tree's orientation.

    Flipping patch ``k`` changes the energy ``s' G s - 2 c' s`` by
    ``4 (G_kk - s_k (G s)_k + c_k s_k)``. The relaxed minimum, rounded, is the
    start; then single flips are made, the best first, while one lowers the
    energy, where turning a patch away from the tree's orientation must lower
    it by ``TUNING.flip_margin`` times the patch's query weight (a residual of
    about 1/2 at each of its queries) and turning it back may raise it by as
    much: evidence too weak to tell (noise, a coarse part) leaves the tree's
    orientation.
    """
    relaxed = np.linalg.lstsq(G, c, rcond=None)[0]
    margin = TUNING.flip_margin * 2.0 * np.bincount(label, weights=weight, minlength=c.size)
    # a patch without sources has a zero row of G: the rounding of its 0 must not turn it
    sign = np.where((relaxed < 0) & (margin > 0), -1.0, 1.0)
    diag = np.diag(G)
    for _ in range(4 * sign.size):
        change = 4.0 * (diag - sign * (G @ sign) + c * sign)
        cost = change + np.where(sign > 0, margin, -margin)
        k = int(np.argmin(cost))
        if cost[k] >= 0.0:
            break
        sign[k] = -sign[k]
    return sign
