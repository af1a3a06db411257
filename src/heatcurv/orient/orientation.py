"""Orientation: give the unoriented PCA normals one side, the side a user expects.

A PCA normal (:func:`heatcurv.orient.normals.pca_normals`) is an axis; every curvature
sign depends on which way along it the normal points. Three policies
(``estimate(orient=...)``):

``"outward"``
    Closed objects: away from the enclosed volume. One orientation is
    propagated over a minimum spanning tree of the neighbour graph (Hoppe et al.
    1992), then each connected component gets the sign that makes
    ``sum_i A_i n_i . (x_i - c)`` positive (3 x the volume of a closed surface).
    Where the two sides of a thin part (a leg, an ear) are closer than the
    ball, one wrong tree edge turns the whole part inside out; so the tree is
    cut into patches whose sides the generalised winding number chooses
    together, and the points whose side it contradicts are flagged
    (:mod:`heatcurv.orient.enclosure`). A cloud whose winding number does not look
    like a closed surface's (an open sheet) keeps the tree's orientation.
``"up"``
    Terrain, buildings, aerial LiDAR: towards ``+z`` (the sky).
``"viewpoint"``
    Range scans: towards the scanner, one position or one per point.

``orient="auto"`` (the default) picks ``"viewpoint"`` when a viewpoint is
given; otherwise :func:`heatcurv.orient.auto.auto_policy` looks at a sample of the cloud (the
scale choice's sample centres, :func:`heatcurv.geometry.sampling.key_sample`, so
that a tiled run decides alike): an open surface spread over the horizontal
plane (terrain, roofs, a range scan from above: most normals within 45
degrees of vertical, and almost none facing down once the sample is
consistently oriented) is oriented ``"up"``; an open surface spread over
another plane alike, along that plane's normal towards its convex side (a
convention on the axis when it is nearly flat); anything else ``"outward"``. A
closed surface is never taken for terrain: by the divergence theorem its
outward normals have ``sum_i A_i n_z,i = 0``, as much facing down as up.
An ``"outward"`` cloud the winding number finds open keeps each component's
outward vote (its convex side out), or the flat-patch convention;
:attr:`OrientationReport.reason` says which rule oriented the cloud.

For ``"up"`` and ``"viewpoint"`` every normal clearly facing or clearly facing
away from its reference direction ``r_i`` (``|n_i . r_i| >= TUNING.anchor_cosine``)
is an *anchor*, oriented on its own; the others (walls for ``"up"``, grazing
views for ``"viewpoint"``) take their side from their neighbours by a bounded
local propagation (:func:`local_sides`): in rounds, every point not yet
decided takes the side its decided graph neighbours vote for, each vote
``s_ij`` (below) weighted by how well the edge stays in both tangent planes,
for at most ``TUNING.local_hops`` rounds. A point's side then depends only on
the points a few balls around it (:attr:`Orientation.reach`), never on how
far the cloud goes on: a tile of a tiled run (:mod:`heatcurv.tiles`) whose
halo holds that reach gives every point the side the whole cloud gives it.
A spanning tree would carry a wall's side from the nearest anchor *along
the tree*, a path a tile's piece of the cloud cannot reproduce: points of a
tiled ``lidar_tile`` would take another side than in one piece.
Points no anchor reaches within the rounds are flagged ambiguous and face
their reference direction.

``"outward"`` has no local reference: its spanning tree is global, and a
tiled run makes its pieces agree afterwards (:mod:`heatcurv.tiles.orient`).

The spanning tree compares two normals by ``s_ij = n_i . n_j - (n_i . e)(n_j
. e)`` (``e`` the unit edge): their agreement once the components along the
edge are removed, which equals ``n_i . n_j`` on a smooth surface but stays
clear across a sharp edge (0.5 at a right angle), where ``n_i . n_j`` is near
0 and the plain Hoppe rule flips at random (it turns a closed pancake
ellipsoid half inside out). The edge cost is ``1 - |s_ij|`` plus how
far the edge leaves the tangent planes, ``max(|n_i . e|, |n_j . e|)``: an edge
across a thin part (an ear, a sheet, a fin) joins parallel normals of
opposite sides, which the plain Hoppe cost takes for the cheapest edge of all
and which then turns one side inside out (on a 28k-point bunny scan, the
back of an ear).

Where no consistent side exists (two sheets closer than the ball, points
no anchor reaches within ``TUNING.local_hops`` rounds, a side the winding
number of a closed cloud contradicts), the points are flagged
*ambiguous*, never silently guessed: :attr:`Orientation.ambiguous`, and
``estimate`` marks them unreliable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from .._kernels import graph as graph_kernels
from .._kernels import segment as kernels
from ..errors import HeatcurvError
from ..geometry.neighbourhood import Neighbourhood
from ..tuning import TUNING
from .enclosure import enclose, patches, sampled_sources

__all__ = [
    "ORIENT_MODES", "GRAPH_NEIGHBOURS", "Orientation", "OrientationReport", "orient",
    "local_sides", "as_viewpoint", "axisless_balls", "AutoPolicy", "tree_sides", "edge_agreement",
    "coordinate_convention",
]

#: The orientation policies of ``estimate(orient=...)``.
ORIENT_MODES = ("outward", "up", "viewpoint")
#: Nearest neighbours per point in the orientation's spanning-tree graph.
GRAPH_NEIGHBOURS = 10


@dataclass(frozen=True)
class OrientationReport:
    """How the normals were oriented (``result.info["orientation"]``).

    Attributes
    ----------
    mode : str
        ``"outward"``, ``"up"``, ``"viewpoint"``, or ``"given"`` (the caller's normals).
    components : int
        Connected components of the orientation graph (outliers, cut out of it, not counted).
    anchored : int
        Points whose side was read off the reference direction (``"up"``,
        ``"viewpoint"``); the others took it from their neighbours.
    by_convention : int
        Points whose side follows a convention on the coordinates, not the
        shape, so that turning the cloud may turn them: nearly flat components
        without a reference direction (the component's least-variance axis,
        largest coordinate positive; right or wrong, their curvature is near 0),
        or every point of a cloud ``orient="auto"`` oriented ``"up"``.
    ambiguous : int
        Points with no consistent side (flagged unreliable).
    closed : bool or None
        ``"outward"``: whether the winding number found the cloud to enclose
        a volume (:mod:`heatcurv.orient.enclosure`); None for the other modes and
        for a tile's piece of a cloud.
    turned : int
        Points whose side the winding number turned over (closed clouds).
    escaped : int
        Points not reliable turned over, after the fit, to the side their rays
        escape from (closed and undecided clouds; :mod:`heatcurv.orient.visibility`).
    unsupported : int
        Points whose side the winding number contradicts (closed clouds;
        counted in ``ambiguous`` too).
    agreement : float or None
        ``"outward"`` on a whole cloud: the share of its area whose winding-number
        levels agree with their sides (:class:`heatcurv.orient.enclosure.PatchSides`);
        None otherwise.
    outside_share : float or None
        With ``agreement``: the share of the area whose outside level is near 0
        (the normals point out of something; an open sheet's field there is about -1/2).
    undecided : bool
        ``"outward"``: the winding number could not tell whether the cloud
        encloses a volume (``TUNING.undecided_share``): its
        sides are the field's and every point is flagged (``unsupported``).
    open_components : int
        ``"outward"``, a cloud ``closed`` or ``undecided``: its objects that are
        open on their own (an open sheet beside a closed object), which keep
        their outward vote (or the flat convention) and whose sides the winding
        number neither turns nor flags (:func:`heatcurv.orient.enclosure.patch_sides`).
    upward_components : int
        ``"outward"`` chosen by ``orient="auto"``: the objects open on their own
        (or, on an open cloud, any of its objects) that lie over the horizontal
        plane and were made to face ``+z`` (terrain beside a building, the
        ground a boulder lies on), as ``"auto"`` orients such an object alone;
        their points count in ``by_convention``.
    reason : str
        Which rule chose the sides, in words (``orient="auto"``: why this mode).
    policy : AutoPolicy or None
        ``orient="auto"`` without a viewpoint: the choice and the numbers it was made on.
    axisless : int
        ``"up"``, ``"viewpoint"``: points whose ball has no normal axis
        (``TUNING.axisless_ball``: a tree crown's scatter, a wire, strong
        noise), whose normal starts from the reference direction itself.
    on_anchors : int
        0 when every point's normal was oriented over the points' graph; else
        the noise swamped the operator's balls and the normals were oriented
        over this many anchors of the wide kernel (:mod:`heatcurv.fits.anchors`), the
        counts above then being anchors, except ``ambiguous``.
    """

    mode: str
    components: int = 0
    anchored: int = 0
    by_convention: int = 0
    ambiguous: int = 0
    on_anchors: int = 0
    closed: bool | None = None
    turned: int = 0
    escaped: int = 0
    unsupported: int = 0
    agreement: float | None = None
    outside_share: float | None = None
    undecided: bool = False
    open_components: int = 0
    upward_components: int = 0
    axisless: int = 0
    reason: str = ""
    policy: AutoPolicy | None = None


@dataclass(frozen=True)
class Orientation:
    """Oriented normals and what could not be oriented.

    Attributes
    ----------
    normals : ndarray, shape (n, 3)
        The input normals, flipped where needed.
    ambiguous : ndarray, shape (n,), bool
        No consistent side: in-plane neighbours pointing the other way,
        (``"up"``, ``"viewpoint"``) no anchor within ``TUNING.local_hops`` edges,
        or (``"outward"``, a closed cloud) a side the winding number
        contradicts (:attr:`OrientationReport.unsupported`).
    report : OrientationReport
    reach : ndarray, shape (n,), optional
        ``"up"`` and ``"viewpoint"``: how far from each point (in the points'
        unit) the sides of the points of its ball read: its ball radius plus
        the most by which the side of it or of a graph neighbour reads beyond
        that point's own ball (:func:`local_sides`; 0 for anchors, several
        balls on a wall whose side came from the roof or the ground). The
        estimator's ``info["reach"]`` is the fit's support plus this, as it
        is the support plus the ball radius for the normals (neighbours' balls
        taken as about as wide as the point's own). None for ``"outward"``,
        whose spanning tree is global.
    patch : ndarray, shape (n,), int, optional
        ``"outward"`` on a part of a cloud (a tile): the pieces of the spanning
        forest whose sides the winding number chooses over the whole cloud
        (:func:`heatcurv.orient.enclosure.patches`; -1 for excluded points). None otherwise.
    sources : ndarray, shape (n,), bool, optional
        With ``patch``: the part's share of the winding number's sources
        (:func:`heatcurv.orient.enclosure.sampled_sources`). On a whole cloud
        the winding number found closed or undecided: the sources its sums ran
        over (the occluders of :mod:`heatcurv.orient.visibility`). None otherwise.
    weights : ndarray, shape (n,), optional
        With ``patch``: the sources' dipole strengths (the areas, 0 for excluded points).
    fine : ndarray, shape (n,), int, optional
        With ``patch``: each patch cut finer (:func:`heatcurv.orient.enclosure.patches`), the
        pieces the winding number solves for where a patch's one side is contradicted.
    roundness : ndarray, shape (n,), optional
        With ``patch``: the balls' PCA roundness ``lambda_0 / lambda_1``, which
        the winding number reads at its sources (:func:`heatcurv.orient.enclosure.patch_sides`).
    open : ndarray, shape (n,), bool, optional
        With ``sources`` on a whole cloud: the points of objects open on their own
        (:attr:`OrientationReport.open_components`), which keep their sides; None when there are none.
    """

    normals: np.ndarray
    ambiguous: np.ndarray
    report: OrientationReport
    reach: np.ndarray | None = None
    patch: np.ndarray | None = None
    sources: np.ndarray | None = None
    weights: np.ndarray | None = None
    fine: np.ndarray | None = None
    roundness: np.ndarray | None = None
    open: np.ndarray | None = None


def as_viewpoint(viewpoint, n: int | None = None) -> np.ndarray:
    """Validate a sensor position: shape (3,), or (n, 3) one per point, finite; returned as float64."""
    try:
        v = np.asarray(viewpoint, dtype=np.float64)
    except (TypeError, ValueError):
        v = np.empty(0)
    per_point = n is not None and v.shape == (n, 3)
    if not (v.shape == (3,) or per_point) or not np.all(np.isfinite(v)):
        shape = "3 finite numbers (x, y, z)" + ("" if n is None else f" or an ({n}, 3) array of positions")
        raise HeatcurvError(f"viewpoint must be {shape}, got an array of shape {v.shape}"
                            if v.ndim > 1 or v.size > 3 else f"viewpoint must be {shape}, got {viewpoint!r}")
    return v


@dataclass(frozen=True)
class AutoPolicy:
    """What ``orient="auto"`` chose for a cloud without a viewpoint (:func:`heatcurv.orient.auto.auto_policy`).

    Attributes
    ----------
    mode : str
        ``"up"`` or ``"outward"``.
    vertical : float
        Share of the sample's normals within 45 degrees of vertical (``|n_z| >= TUNING.auto_vertical_cosine``).
    down : float
        Once the sample is consistently oriented (per connected component,
        either side), the share of ``sum_i |n_z,i|`` over its flat points on
        those facing down (the smaller of the two sums): 0 for a surface over
        the horizontal plane, 1/2 for a closed one.
    layered : float
        Share of the sample's flat, near-horizontal points with another
        sample point straight above or below them (``TUNING.auto_layered_share``):
        near 0 for a surface over the horizontal plane, large for a thin
        closed object lying flat.
    split : float
        Share of the sample's points whose balls' residuals split in two
        layers (``TUNING.auto_split_share``): large for a plate too thin for
        ``layered``.
    flat : float
        Share of the sample's points whose balls are flat
        (``TUNING.auto_flatness``): most of a surface's; near 0 where noise as
        thick as the sample's balls leaves no surface to read, and then no
        share above says anything (``TUNING.auto_flat_share``).
    towards : tuple of float or None
        ``"up"`` along the sample's own axis (a surface over a plane turned
        away from horizontal): the unit direction the normals face, shape (3,),
        the shares above then measured against it instead of ``z``; None for
        ``+z``.
    convex : bool
        With ``towards``: whether its side is the surface's convex side
        (:func:`heatcurv.orient.auto.convex_side`), which turns with the cloud, rather than a
        convention on the coordinates (a nearly flat surface).
    """

    mode: str
    vertical: float
    down: float
    layered: float = 0.0
    split: float = 0.0
    flat: float = 1.0
    towards: tuple | None = None
    convex: bool = False

    @property
    def reason(self) -> str:
        """Why, in words: the report's :attr:`OrientationReport.reason`."""
        axis = "vertical" if self.towards is None else "the axis"
        measured = (f"{100 * self.flat:.0f} % of the sampled balls flat, "
                    f"{100 * self.vertical:.0f} % of the sampled normals within 45 degrees of {axis}; "
                    f"consistently oriented, {100 * self.down:.1f} % of their extent along it faces the other way; "
                    f"{100 * self.layered:.0f} % of the flat ones lie over or under another sheet, "
                    f"{100 * self.split:.0f} % have balls split in two layers")
        if self.mode == "up" and self.towards is None:
            return f"auto: an open surface over the horizontal plane, oriented up (+z) ({measured})"
        if self.mode == "up":
            return f"auto: an open surface over the plane across its normals' axis, oriented {self.along} ({measured})"
        return f"auto: not a surface over a plane ({measured})"

    @property
    def along(self) -> str | None:
        """``"up"`` along the cloud's own axis: which way, in words; None otherwise."""
        if self.towards is None:
            return None
        side = "its convex side" if self.convex else "the axis's largest coordinate positive, a convention"
        return f"along ({', '.join(f'{c:.3f}' for c in self.towards)}), {side}"


def orient(
    points: np.ndarray,
    normals: np.ndarray,
    nbhd: Neighbourhood,
    areas: np.ndarray | None = None,
    *,
    mode: str = "outward",
    towards=None,
    graph_neighbours: int | None = GRAPH_NEIGHBOURS,
    excluded: np.ndarray | None = None,
    whole_cloud: bool = True,
    cloud_points: int | None = None,
    roundness: np.ndarray | None = None,
    open_up: bool = False,
) -> Orientation:
    """Orient unoriented normals by one of :data:`ORIENT_MODES`.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Distinct points.
    normals : ndarray, shape (n, 3)
        Unit normals of arbitrary sign.
    nbhd : Neighbourhood
        Neighbour graph the orientation is propagated over.
    areas : ndarray, shape (n,), optional
        Per-point areas weighting the votes (equal weights if omitted).
    mode : {"outward", "up", "viewpoint"}
    towards : array_like, optional
        ``"up"``: the up direction, shape (3,) (default ``(0, 0, 1)``).
        ``"viewpoint"``: the sensor position, shape (3,), or one per point,
        shape (n, 3), in the coordinates of ``points``.
    graph_neighbours : int or None, optional
        Propagate over this many of each point's neighbours (None: all): the
        nearest half and the rest spread to the ball's edge
        (:meth:`~heatcurv.geometry.neighbourhood.Neighbourhood.spread`), so the graph
        stays connected on anisotropic scans and costs little (on a million
        points: 13 s with 60 neighbours, 1.9 s with 10).
    excluded : ndarray, shape (n,), bool, optional
        Points cut out of the graph (outliers, :mod:`heatcurv.flags.outliers`): no
        orientation is propagated through them and they take no part in any
        vote (each is a component of its own, oriented by its own outward
        side). Without this, a far stray point's long edges, whose normal is
        that of a whole distant chunk of the surface, can bridge regions of
        the spanning tree and turn part of a closed surface inside out
        (about half of a grid-sampled torus with three points 25 diagonals
        away).
    whole_cloud : bool, optional
        ``"outward"``: whether ``points`` is the whole cloud, whose inside the
        winding number decides (:mod:`heatcurv.orient.enclosure`). A tile's piece is
        not: its pieces' sides are made to agree by :mod:`heatcurv.tiles.orient`,
        and the winding number's patches (:attr:`Orientation.patch`) are cut
        here and signed over the whole cloud by :mod:`heatcurv.tiles.winding`.
    cloud_points : int, optional
        Points of the whole cloud (``whole_cloud`` False): the patches are cut
        to the size the whole cloud's would have.
    roundness : ndarray, shape (n,), optional
        ``"up"`` and ``"viewpoint"``: each ball's ``lambda_0 / lambda_1``
        (:func:`heatcurv.orient.normals.pca_normals`). A ball from
        ``TUNING.axisless_ball`` on has no normal axis (a tree crown's
        scatter, a wire): its normal becomes the reference direction itself,
        so that no sample decides it (the estimator flags it unless its fit
        finds a surface there).
    open_up : bool, optional
        ``"outward"`` chosen by ``orient="auto"``: a closed cloud's objects open
        on their own, and an open cloud's objects, that lie over the horizontal
        plane face ``+z`` (:func:`heatcurv.orient.enclosure.patch_sides`) instead
        of keeping their outward vote.

    Returns
    -------
    Orientation
    """
    if mode not in ORIENT_MODES:
        raise HeatcurvError(f"orient must be one of {', '.join(map(repr, ORIENT_MODES))}, got {mode!r}")
    n = points.shape[0]
    graph = nbhd if graph_neighbours is None else nbhd.spread(int(graph_neighbours))
    w = np.ones(n) if areas is None else np.abs(areas)
    if excluded is not None:
        excluded = np.asarray(excluded, dtype=bool)
        graph = graph.without(excluded)
        w = np.where(excluded, 0.0, w)
    reference = _reference_directions(points, mode, towards)
    if reference is not None:
        return _orient_locally(points, normals, graph, reference, mode, excluded, roundness)

    oriented, tree, labels = tree_sides(points, normals, graph)
    n_comp = int(labels.max()) + 1

    # the sign of each component: outward vote, else the flat convention
    sign, convention = _component_signs(points, oriented, labels, n_comp, w)
    oriented *= sign[labels][:, None]

    # the winding number decides inside from outside, part by part, and flags what it contradicts
    unsupported, closed, undecided, turned, part = np.zeros(n, dtype=bool), None, False, 0, {}
    agreement = outside_share = None
    left_open, open_components = np.zeros(n, dtype=bool), 0  # objects of a closed cloud open on their own
    upward, upward_components = np.zeros(n, dtype=bool), 0  # objects over the ground made to face +z
    if not whole_cloud:
        cut = np.zeros(n, dtype=bool) if excluded is None else excluded
        patch, fine = patches(points, tree, cut, cloud_points)
        part = {"patch": patch, "fine": fine, "weights": w, "roundness": roundness,
                "sources": sampled_sources(points, cut, n if cloud_points is None else cloud_points)}
    else:
        enclosure = enclose(points, oriented, tree, w, nbhd, excluded, roundness, open_up)
        oriented, unsupported, closed, undecided, turned = (
            enclosure.normals, enclosure.unsupported, enclosure.closed, enclosure.undecided, enclosure.flipped)
        part = {"sources": enclosure.sources, "open": enclosure.open}
        agreement, outside_share = enclosure.agreement, enclosure.outside_share
        if enclosure.open is not None:
            left_open, open_components = enclosure.open, enclosure.open_components
        if enclosure.upward is not None:
            upward, upward_components = enclosure.upward, enclosure.upward_components
    ambiguous = _conflicting(points, oriented, graph) | unsupported
    report = OrientationReport(
        mode=mode, components=_surface_components(labels, excluded),
        by_convention=int(np.sum((convention[labels] & (left_open if closed or undecided else True)) | upward)),
        ambiguous=int(ambiguous.sum()),
        closed=closed, turned=turned, unsupported=int(unsupported.sum()), agreement=agreement,
        outside_share=outside_share, undecided=undecided, open_components=open_components,
        upward_components=upward_components,
    )
    return Orientation(oriented, ambiguous, report, **part)


def _orient_locally(points, normals, graph, reference, mode, excluded, roundness=None) -> Orientation:
    """``"up"`` and ``"viewpoint"``: anchors by their reference direction, the others by :func:`local_sides`.

    A ball without a normal axis (``roundness`` from ``TUNING.axisless_ball``)
    gets the reference direction: its PCA axis is whichever of two about equal
    variances the sample made smaller, and turns with it. Its side is not
    flagged here: a noisy surface's ball can be as round, and its fit finds
    the surface (:func:`heatcurv.estimator.estimate` judges it by the fit).
    """
    facing = np.einsum("ij,ij->i", normals, reference)
    anchors = np.abs(facing) >= TUNING.anchor_cosine
    facing_side = np.where(facing < 0, -1.0, 1.0)
    side, own_reach = local_sides(points, normals, graph, np.where(anchors, facing_side, 0.0))
    undecided = side == 0
    oriented = normals * np.where(undecided, facing_side, side)[:, None]
    ambiguous = _conflicting(points, oriented, graph) | undecided
    axisless = np.zeros(points.shape[0], dtype=bool) if roundness is None else axisless_balls(roundness, mode)
    oriented[axisless] = reference[axisless]
    if excluded is not None:
        ambiguous &= ~excluded  # an outlier's own side: it is flagged an outlier already
    reach = row_reach(own_reach, graph)
    n_comp, labels = csgraph.connected_components(_symmetric(graph), directed=False)
    report = OrientationReport(
        mode=mode, components=_surface_components(labels, excluded), anchored=int(anchors.sum()),
        ambiguous=int(ambiguous.sum()), axisless=int(axisless.sum()),
    )
    return Orientation(oriented, ambiguous, report, reach)


def local_sides(points: np.ndarray, normals: np.ndarray, graph: Neighbourhood, sides: np.ndarray,
                hops: int = TUNING.local_hops) -> tuple[np.ndarray, np.ndarray]:
    """Carry the anchors' sides over the graph in ``hops`` synchronous rounds; each point's side and reach.

    In round ``t`` every undecided point ``i`` sums over its decided graph
    neighbours ``j`` (its own row: edges to the points of its ball)

    ``v_i = sum_j s_ij (1 - max(|n_i . e_ij|, |n_j . e_ij|))_+ side_j``,

    ``s_ij`` the normals' agreement with the edge component removed
    (:func:`edge_agreement`: 0.5 across a right-angled edge such as a wall's
    eave or foot, so a roof or the ground carries its side onto the wall) and
    the second factor 0 for an edge along the normals (across a thin part,
    between two sides of a sheet); it takes the side ``sign(v_i)`` when
    ``v_i != 0``. A point's side thus depends only on the points within
    ``t`` edges, and on their balls (their normals): never on how far the
    cloud goes on, so that any part of the cloud holding that reach gives the
    same sides.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    normals : ndarray, shape (n, 3)
        Unit normals of arbitrary sign.
    graph : Neighbourhood
        The propagation graph (each row: the edges to a point's neighbours),
        with each point's ball radius ``graph.radius`` (its normal's support).
    sides : ndarray, shape (n,)
        ``+1`` or ``-1`` for the anchors (keep, or flip the normal), ``0`` for
        the points to decide.
    hops : int
        Rounds.

    Returns
    -------
    side : ndarray, shape (n,)
        ``+1``, ``-1``, or ``0`` for the points no anchor reached.
    reach : ndarray, shape (n,)
        How far from each point lie the points its side (or its being
        undecided) depends on: an anchor's ball radius; for the others, each
        round they take part in raises it to ``max_j |xi - xj| + reach_j``
        over the row, ``reach_j`` as of the round before.
    """
    side = np.array(sides, dtype=np.float64)
    reach = np.array(graph.radius, dtype=np.float64)
    todo = np.flatnonzero(side == 0)
    if todo.size == 0:
        return side, reach
    # the rows of the points to decide, and each vote's weight, computed once
    lo, counts = graph.indptr[todo], graph.counts[todo]
    pair = np.repeat(lo - (np.cumsum(counts) - counts), counts) + np.arange(counts.sum())
    row, col, dist = np.repeat(todo, counts), graph.indices[pair], graph.distances[pair]
    weight = edge_agreement(points, normals, row, col) * np.clip(1.0 - _edge_tilt(points, normals, row, col), 0, None)
    for done in range(int(hops)):
        # synchronous: every undecided point's state (side, or still none) follows from its row's
        # states in the round before, so its reach grows by one edge per round
        slot = np.repeat(np.arange(todo.size), counts)
        vote = np.bincount(slot, weights=weight * side[col], minlength=todo.size)
        reach[todo] = np.maximum(reach[todo], _segment_max(dist + reach[col], counts))
        decided = vote != 0
        side[todo[decided]] = np.where(vote[decided] < 0, -1.0, 1.0)
        keep = ~decided[slot]
        todo, counts, col, dist, weight = todo[~decided], counts[~decided], col[keep], dist[keep], weight[keep]
        if todo.size == 0:
            break
        if not decided.any():
            # nothing changes any more; the undecided points' state still reads every round's reach
            for _ in range(done + 1, int(hops)):
                reach[todo] = np.maximum(reach[todo], _segment_max(dist + reach[col], counts))
            break
    return side, reach


def _edge_tilt(points, normals, i, j) -> np.ndarray:
    """``max(|n_i . e|, |n_j . e|)``, ``e`` the unit edge ``xi -> xj``: how far the edge leaves the tangent planes."""
    edge = points[j] - points[i]
    length = np.linalg.norm(edge, axis=1)
    edge = np.divide(edge, length[:, None], out=np.zeros_like(edge), where=length[:, None] > 0)
    return np.maximum(np.abs(np.einsum("ij,ij->i", normals[i], edge)),
                      np.abs(np.einsum("ij,ij->i", normals[j], edge)))


def row_reach(own_reach: np.ndarray, graph: Neighbourhood) -> np.ndarray:
    """How far the sides a point's values read reach, shape (n,): its own side's and its ball's.

    Beyond its own ball, a point's values read its neighbours' sides (its
    ambiguity flag; its fit, in the estimator): its ball radius plus the most
    by which any side in its row reads beyond that point's ball.

    Parameters
    ----------
    own_reach : ndarray, shape (n,)
        How far from each point its own side was read.
    graph : Neighbourhood
        The points' balls.
    """
    excess = own_reach - graph.radius
    return graph.radius + np.maximum(excess, _segment_max(excess[graph.indices], graph.counts))


def _segment_max(values: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Maximum of ``values`` over consecutive segments of ``counts`` entries (0 if empty), shape (len(counts),)."""
    out = np.zeros(counts.shape[0])
    full = counts > 0
    if full.any():
        out[full] = np.maximum.reduceat(values, (np.cumsum(counts) - counts)[full])
    return out


def _symmetric(graph: Neighbourhood) -> sp.csr_matrix:
    """The graph's pairs as a sparse matrix, shape (n, n) (connected components ignore the direction)."""
    n = graph.n_points
    return sp.csr_matrix((np.ones(graph.n_pairs), graph.indices, graph.indptr), shape=(n, n))


def _surface_components(labels: np.ndarray, excluded: np.ndarray | None) -> int:
    """Components of the orientation graph that hold a point not excluded (each outlier is one of its own)."""
    kept = labels if excluded is None else labels[~excluded]
    return int(np.unique(kept).size)


def _conflicting(points: np.ndarray, normals: np.ndarray, graph: Neighbourhood) -> np.ndarray:
    """Points whose in-plane, aligned neighbours point the other way, shape (n,), bool.

    A neighbour ``j`` of ``i`` is compared when the edge lies near the tangent
    plane, ``|n_i . (xj - xi)| <= TUNING.conflict_in_plane |xj - xi|``, and the normal
    axes agree, ``|n_i . n_j| >= TUNING.conflict_aligned``; a point conflicts when at
    least two and at least ``TUNING.conflict_share`` of the compared ones have
    ``n_i . n_j < 0``.
    """

    counts = kernels.orientation_conflicts(
        points, normals, graph.indptr, graph.indices, graph.distances, TUNING.conflict_in_plane, TUNING.conflict_aligned
    )
    compared, against = counts[:, 0], counts[:, 1]
    return (against >= 2) & (against >= TUNING.conflict_share * compared)


def _reference_directions(points: np.ndarray, mode: str, towards) -> np.ndarray | None:
    """The direction each normal should face, shape (n, 3) (not unit), or None for ``"outward"``."""
    if mode == "outward":
        return None
    if mode == "up":
        up = np.array([0.0, 0.0, 1.0]) if towards is None else as_viewpoint(towards)
        if not np.linalg.norm(up) > 0:
            raise HeatcurvError("the up direction must not be the zero vector")
        return np.broadcast_to(up / np.linalg.norm(up), points.shape)
    if towards is None:
        raise HeatcurvError("orient='viewpoint' needs a viewpoint (the sensor position)")
    to_sensor = as_viewpoint(towards, points.shape[0]) - points
    length = np.linalg.norm(to_sensor, axis=1)
    if np.any(length == 0):
        raise HeatcurvError("the viewpoint coincides with a point of the cloud; give the sensor's position")
    return to_sensor / length[:, None]


def axisless_balls(roundness: np.ndarray, mode: str) -> np.ndarray:
    """The balls without a normal axis whose normal starts from the reference direction, shape (n,), bool.

    ``roundness`` is each ball's ``lambda_0 / lambda_1``; from
    ``TUNING.axisless_ball`` on its two smallest variances are about equal.
    Only ``"up"`` and ``"viewpoint"`` have a reference direction (all False
    otherwise); NaN (a ball of one line, given normals) compares False.
    """
    if mode not in ("up", "viewpoint"):
        return np.zeros(np.shape(roundness), dtype=bool)
    return np.asarray(roundness) >= TUNING.axisless_ball


def _spanning_forest(points: np.ndarray, normals: np.ndarray, graph: Neighbourhood) -> sp.csr_matrix:
    """Minimum spanning forest of the neighbour graph, symmetric, shape (n, n).

    Every stored entry is an undirected edge, so the directed neighbour graph
    needs no symmetrising; of a mutual pair's two costs the cheaper counts.
    The forest is found by a compiled Boruvka
    (:func:`heatcurv._kernels.graph.minimum_spanning_forest`): the same
    entries as ``csgraph.minimum_spanning_tree``, without its sort of the
    costs. Costs are strictly positive.
    """
    n = points.shape[0]
    cost = kernels.orientation_costs(points, normals, graph.indptr, graph.indices, graph.distances, graph.radius)
    kept = np.flatnonzero(graph_kernels.minimum_spanning_forest(graph.indptr, graph.indices, cost))
    # the kept entries as CSR, rows in order: each row starts after the kept entries before its first
    tree = sp.csr_matrix((cost[kept], graph.indices[kept], np.searchsorted(kept, graph.indptr)), shape=(n, n))
    return (tree + tree.T).tocsr()


def tree_sides(points: np.ndarray, normals: np.ndarray, graph: Neighbourhood):
    """One side carried over the minimum spanning forest of ``graph``, from the first point of each tree.

    Returns
    -------
    oriented : ndarray, shape (n, 3)
        ``normals``, each flipped or not to agree with its tree's root (:func:`edge_agreement` along the edges).
    forest : scipy.sparse.csr_matrix, shape (n, n)
        The symmetric forest (:func:`_spanning_forest`).
    labels : ndarray, shape (n,)
        The tree (connected component) of every point.
    """
    forest = _spanning_forest(points, normals, graph)
    _, labels = csgraph.connected_components(forest, directed=False)
    roots = np.zeros(points.shape[0], dtype=bool)
    roots[np.unique(labels, return_index=True)[1]] = True
    parity = graph_kernels.forest_parity(forest.indptr, forest.indices, roots, points, normals)
    return normals * np.where(parity, -1.0, 1.0)[:, None], forest, labels


def edge_agreement(points, normals, i, j) -> np.ndarray:
    """``s_ij = n_i . n_j - (n_i . e)(n_j . e)``, ``e`` the unit edge ``xi -> xj``, shape (len(i),).

    The normals' dot product once their components along the edge are
    removed: ``n_i . n_j`` on a smooth surface (where the edge is tangent), and
    still clearly positive for consistent normals across a sharp edge (0.5 at
    a right-angled one, convex or concave), where ``n_i . n_j`` is about 0 and
    its sign is noise. Negative: one of the two normals must flip.

    Parameters
    ----------
    points, normals : ndarray, shape (n, 3)
        The points and their unit normals.
    i, j : ndarray of int, shape (m,)
        The edges' ends.
    """
    edge = points[j] - points[i]
    length = np.linalg.norm(edge, axis=1)
    edge = np.divide(edge, length[:, None], out=np.zeros_like(edge), where=length[:, None] > 0)
    ni, nj = normals[i], normals[j]
    return np.einsum("ij,ij->i", ni, nj) - np.einsum("ij,ij->i", ni, edge) * np.einsum("ij,ij->i", nj, edge)


def coordinate_convention(axis: np.ndarray) -> np.ndarray:
    """``axis`` (shape (3,), unit) turned so that its largest coordinate is positive: a side chosen by the
    coordinates, for a surface too flat (or a vote too weak) to have one of its own."""
    return axis * np.sign(axis[np.argmax(np.abs(axis))])


def _component_signs(points, oriented, labels, n_comp, w):
    """Sign of every component of the ``"outward"`` orientation, shape (n_comp,).

    Outward when the vote ``sum_i A_i n_i . (x_i - c)`` is clear (closed
    surfaces, bowls, caps); otherwise a nearly flat patch's mean normal is
    made to point along the positive side of its least-variance axis (whose
    largest coordinate is made positive), a convention.

    Returns
    -------
    sign : ndarray, shape (n_comp,)
    convention : ndarray, shape (n_comp,), bool
    """
    count = np.bincount(labels, weights=w, minlength=n_comp)
    centroid = np.stack([np.bincount(labels, weights=w * points[:, k], minlength=n_comp) for k in range(3)], 1)
    centroid /= np.maximum(count, np.finfo(float).tiny)[:, None]  # weightless (excluded) components: 0
    radial = np.einsum("ij,ij->i", oriented, points - centroid[labels]) * w
    vote = np.bincount(labels, weights=radial, minlength=n_comp)
    strength = np.bincount(labels, weights=np.abs(radial), minlength=n_comp)
    sign = np.where(vote < 0, -1.0, 1.0)
    # a component without weight (excluded points) keeps its propagated side: nothing to decide
    weak = (count > 0) & (np.abs(vote) <= TUNING.weak_vote * strength)
    convention = np.zeros(n_comp, dtype=bool)
    for c in np.flatnonzero(weak):  # nearly flat patches: few components, small loop
        member = labels == c
        rel = points[member] - centroid[c]
        axis = coordinate_convention(np.linalg.svd(rel, full_matrices=False)[2][-1])
        sign[c] = -1.0 if oriented[member].sum(axis=0) @ axis < 0 else 1.0
        convention[c] = True
    return sign, convention
