"""Inside and outside across tiles: the winding number's patch signs and flags over the whole cloud.

In memory, a closed cloud's outward orientation is finished by the
generalised winding number (:mod:`heatcurv.orient.enclosure`): the spanning forest is
cut into patches, each patch gets the side that makes the field about 1 inside
and 0 outside, and the points whose side the field contradicts are flagged.
Without it the two sides of a thin part (a leg, an ear) can both be oriented
by one wrong edge of the tree, and the part comes out inside out, flagged
reliable.

A tile cuts its own spanning forest into patches of the size the whole
cloud's would have (:func:`heatcurv.orient.enclosure.patches`, each also within one
seam piece of :mod:`.orient`) and keeps a sample of its core points as
sources, with the normals and areas the winding number reads in memory (the
spanning tree's PCA normals, the operator's areas): those whose coordinate
rank (:func:`heatcurv.orient.enclosure.source_keys`, the same for a point in any
tile) is at most a threshold chosen for about
:data:`heatcurv.orient.enclosure.MAX_SOURCES` sources over the whole cloud
(:func:`heatcurv.orient.enclosure.sampled_sources`), and the point of lowest
rank of each patch the threshold misses (in memory too every patch holds one). The driver,
once the seam flips are known, gathers every tile's sources, turns their
normals by the seam flips, and solves the same energy for the sides of all
patches of all tiles (:func:`heatcurv.orient.enclosure.patch_sides`; a patch whose side is
contradicted is re-cut into its finer pieces, which every tile cuts too, as in memory). A closed cloud's
patch and piece flips are then applied with the seam flips in the output pass, and a
point is flagged (not ``reliable``) when it is a disagreeing source, or when
more than half of the sources within its operator ball (radius ``alpha h``)
disagree, as in memory.

The patches differ from the in-memory run's (a tile's forest is not the whole
cloud's), so on a thin part the two runs can end with different sides or
flags; neither leaves a part inside out and reliable where the other flags it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..geometry.validation import row_hashes
from ..orient.enclosure import patch_sides, sampled_sources, source_keys
from ..orient.visibility import MAX_TESTED, escape_votes, lowest_keys
from ..tuning import TUNING
from .orient import patch_moments
from .output import PATCH_SHIFT, RECORD, SOURCE_KEYS, chunk_flips, keyed_flips, read_results, write_records

__all__ = ["MAX_TILED_PATCHES", "WindingSides", "tile_sources", "winding_sides", "flag_unsupported"]

#: Most patches the driver solves for. The energy holds two fields and a matrix of the sources' queries
#: by the patches (about 6000 x 3 x 8 bytes a patch) and its single-patch flips cost the patch count
#: cubed; past this many (clouds in thousands of tiles) each tile's seam pieces are the patches.
MAX_TILED_PATCHES = 1500


def tile_sources(frame, points: np.ndarray, rows: np.ndarray, seam: np.ndarray, results: dict,
                 winding: dict | None) -> dict:
    """A tile's winding patch of every core row and its share of the sources (:data:`.output.SOURCE_KEYS`).

    Parameters
    ----------
    frame : heatcurv.choice.choices.CloudFrame
        The whole cloud's frame.
    points : ndarray, shape (c, 3)
        The tile's core points, input coordinates.
    rows : ndarray, shape (c,), int
        Their input rows.
    seam : ndarray, shape (c,), int
        Their seam pieces (:mod:`.orient`).
    results : dict
        Their result fields (``normals``, ``area``, ``outlier``).
    winding : dict or None
        The core rows of the estimate's ``info["winding"]`` (``patch``,
        ``fine``, ``source``, ``normals``, ``weight``, ``roundness``). None (normals oriented on
        anchors): the seam pieces are the patches, and the sources are drawn
        from the results alike.

    Returns
    -------
    dict
        ``winding`` (c,): each row's patch, unique within the tile and within
        one seam piece; ``winding_fine`` (c,): its finer piece, unique within
        the tile; the sources' ``winding_rows``, ``winding_x`` (the frame's
        coordinates), ``winding_normals`` (as the tile oriented them),
        ``winding_area`` (the frame's unit), ``winding_label``,
        ``winding_fine_label``, ``winding_seam``, ``winding_roundness`` (their balls' PCA roundness,
        NaN without ``winding``); ``winding_total``: the summed area of the core rows
        (excluded ones weigh 0), to which the sources' areas are scaled; ``moment_labels``
        (the seam pieces) and ``moments`` (their :func:`.orient.patch_moments` with the
        orientation's normals, which the driver sums into each object's outward vote, as in memory); ``vote_weight``
        (c,) and ``vote_normal`` (c, 3), float32: each row's weight (the frame's unit) and normal in that vote.
    """
    stage = frame.to_stage(points)
    excluded = np.asarray(results["outlier"], dtype=bool)
    if winding is None:
        label = fine = np.unique(seam, return_inverse=True)[1].ravel()
        source = sampled_sources(stage, excluded, frame.n_points)
        normals, weight = results["normals"], np.where(excluded, 0.0, np.abs(results["area"]))
        roundness = np.full(len(points), np.nan)
    else:
        pieces = np.column_stack([seam, np.asarray(winding["patch"], dtype=np.int64)])
        label = np.unique(pieces, axis=0, return_inverse=True)[1].ravel()
        pieces = np.column_stack([pieces, np.asarray(winding["fine"], dtype=np.int64)])
        fine = np.unique(pieces, axis=0, return_inverse=True)[1].ravel()
        source, normals, weight = np.asarray(winding["source"], dtype=bool), winding["normals"], winding["weight"]
        roundness = winding["roundness"]
    # every patch holds a source, as in memory (heatcurv.orient.enclosure's sample plus one a patch): a patch of the
    # core without one (a patch cut by the core's edge) would keep the tile's side whatever the field says
    source = _one_a_patch(source, label, excluded, stage)
    weight = np.abs(weight) / frame.unit**2
    pieces, piece = np.unique(seam, return_inverse=True)
    return {
        "winding": label.astype(np.int64), "winding_fine": fine.astype(np.int64), "winding_rows": rows[source],
        "winding_x": stage[source], "winding_normals": normals[source],
        "winding_area": weight[source], "winding_label": label[source], "winding_fine_label": fine[source],
        "winding_seam": seam[source], "winding_roundness": np.asarray(roundness, dtype=float)[source],
        "winding_total": np.array(weight.sum()),
        "vote_weight": weight, "vote_normal": np.asarray(normals, dtype=np.float32),
        "moment_labels": pieces,
        "moments": patch_moments(stage, normals, weight, piece.ravel(), len(pieces)),
    }


def _one_a_patch(source: np.ndarray, label: np.ndarray, excluded: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``source`` (shape (c,), bool) with each patch (``label``) that holds none given its point of lowest rank.

    The rank is :func:`heatcurv.orient.enclosure.source_keys` of ``x`` (the frame's coordinates): the same
    point whatever the row order; excluded points (outliers) never are sources.
    """
    have = np.zeros(int(label.max(initial=-1)) + 1, dtype=bool)
    have[label[source]] = True
    missing = np.flatnonzero(~excluded & ~have[label])
    if not missing.size:
        return source
    order = missing[np.lexsort((source_keys(x[missing]), label[missing]))]
    source = source.copy()
    source[order[np.unique(label[order], return_index=True)[1]]] = True
    return source


@dataclass(frozen=True)
class WindingSides:
    """The winding step of a tiled run.

    Attributes
    ----------
    column : str
        The ``results.rec`` column the keys are of: ``"winding"`` (the tiles' winding patches), or
        ``"patch"`` (their seam pieces, past :data:`MAX_TILED_PATCHES` winding patches).
    keys : ndarray, shape (p,), int64
        Patch keys (``tile << 32 | label``), sorted.
    flip : ndarray, shape (p,), bool
        Patches to turn over (after the seam flips); when neither ``closed`` nor ``undecided``, only
        those of the objects turned up (``upward_components``).
    fine_keys : ndarray, shape (f,), int64
        The keys of the patches' finer pieces (``results.rec`` column ``"winding_fine"``) that hold a
        source, sorted (:func:`heatcurv.orient.enclosure.patch_sides`).
    fine_flip : ndarray, shape (f,), bool
        Pieces to turn over on top of their patch's flip.
    rows : ndarray, shape (m,), int64
        The sources' input rows, sorted.
    x : ndarray, shape (m, 3)
        Their positions, the frame's coordinates.
    bad : ndarray, shape (m,), bool
        Sources whose side the field contradicts.
    closed : bool
        Whether the cloud encloses a volume (:class:`heatcurv.orient.enclosure.PatchSides`).
    agreement : float
    undecided : bool
        Whether the field cannot tell (:class:`heatcurv.orient.enclosure.PatchSides`): every point is flagged
        but those of ``open``.
    outside_share : float
        (:class:`heatcurv.orient.enclosure.PatchSides`)
    open : ndarray, shape (p,), bool
        The patches of objects open on their own (:attr:`heatcurv.orient.enclosure.PatchSides.open`):
        neither turned nor flagged; all False when neither ``closed`` nor ``undecided``.
    open_components : int
        How many such objects.
    upward_components : int
        The objects open on their own (or, on an open cloud, any object) over the horizontal plane turned
        to face ``+z`` (``open_up``).
    """

    column: str
    keys: np.ndarray
    flip: np.ndarray
    fine_keys: np.ndarray
    fine_flip: np.ndarray
    rows: np.ndarray
    x: np.ndarray
    bad: np.ndarray
    closed: bool
    agreement: float
    undecided: bool = False
    outside_share: float = 0.0
    open: np.ndarray | None = None
    open_components: int = 0
    upward_components: int = 0


def winding_sides(tile_files: dict, seam_keys: np.ndarray, seam_flip: np.ndarray,
                  open_up: bool = False) -> WindingSides | None:
    """Every tile's sources, turned by the seam flips, and the sides of all winding patches.

    Parameters
    ----------
    tile_files : dict of int to str
        Each tile's result file, holding :data:`.output.SOURCE_KEYS`.
    seam_keys, seam_flip : ndarray
        :func:`heatcurv.tiles.orient.seam_flips`' patch keys and flips.
    open_up : bool, optional
        ``orient="auto"``: objects open on their own, and the objects of an open cloud, that lie over
        the horizontal plane face ``+z`` (:func:`heatcurv.orient.enclosure.patch_sides`), as in memory.

    Returns
    -------
    WindingSides or None
        None when fewer than 16 sources were drawn (as in memory: too few to judge).
    """
    parts = {key: [] for key in SOURCE_KEYS}
    for tile, path in sorted(tile_files.items()):
        with np.load(path) as data:
            base = np.int64(tile) << PATCH_SHIFT
            for key in SOURCE_KEYS:
                value = data[key]
                if key in ("winding_label", "winding_fine_label", "winding_seam"):
                    value = base | value.astype(np.int64)
                parts[key].append(np.atleast_1d(value))
    arrays = {key: np.concatenate(value) for key, value in parts.items()}
    rows = arrays["winding_rows"].astype(np.int64)
    if rows.size < 16:
        return None
    order = np.argsort(rows)
    rows, x, nrm = rows[order], arrays["winding_x"][order], arrays["winding_normals"][order]
    area, label, seam = arrays["winding_area"][order], arrays["winding_label"][order], arrays["winding_seam"][order]
    fine_keys, fine = np.unique(arrays["winding_fine_label"][order], return_inverse=True)
    nrm = np.where(keyed_flips(seam, seam_keys, seam_flip)[:, None], -nrm, nrm)
    column = "winding"
    keys, index = np.unique(label, return_inverse=True)
    if keys.size > MAX_TILED_PATCHES:  # the seam pieces: a winding patch lies in one, so their normals agree
        column = "patch"
        keys, index = np.unique(seam, return_inverse=True)
        fine_keys, fine = np.zeros(0, dtype=np.int64), None
    weight = area * (arrays["winding_total"].sum() / area.sum())
    sides = patch_sides(x, nrm, weight, index, keys.size, fine, fine_keys.size, arrays["winding_roundness"][order],
                        open_up=open_up)
    decided = sides.closed or sides.undecided
    # an open cloud keeps the seams' sides but for the objects over the ground turned up (open_up)
    flip = (sides.sign < 0) if decided or sides.upward_components else np.zeros(keys.size, dtype=bool)
    fine_flip = (sides.fine_sign < 0) if decided else np.zeros(fine_keys.size, dtype=bool)
    is_open = sides.open_patches(index, keys.size) if decided else np.zeros(keys.size, dtype=bool)
    return WindingSides(column, keys, flip, fine_keys, fine_flip, rows, x, sides.bad, sides.closed, sides.agreement,
                        sides.undecided, sides.outside_share, is_open, sides.open_components if decided else 0,
                        sides.upward_components)


def flag_unsupported(results_path, source, frame, sides: WindingSides, alpha: float, flips, layer: float = 0.0,
                     chunk: int = 1 << 20) -> tuple[dict, np.ndarray]:
    """Clear ``reliable`` in ``results.rec`` where the winding number contradicts a point's side (closed clouds),
    and find the points not reliable that face away from where their rays escape.

    A source is flagged when it disagrees (:attr:`WindingSides.bad`), and so
    are its exact duplicates; any other point when more than half of the
    sources within its operator ball do (none when no source is that near):
    the ball of radius ``alpha h`` (``h`` the point's ``spacing``), which holds
    the point's neighbours of the in-memory operator (fewer where
    ``min_neighbours`` widened that ball, with the spacings of equations 2.6
    and 2.7).
    When the field is ``undecided``, every point but the outliers is.
    Every point then not reliable (no outlier, not of an object open on its own) is tested as in memory
    (:func:`heatcurv.orient.visibility.escaping_turns`: the sources are the
    occluders, discs across their fitted normals; past
    :data:`heatcurv.orient.visibility.MAX_TESTED` tested points, those of
    lowest coordinate rank).

    Parameters
    ----------
    results_path : str
        ``results.rec``.
    source : heatcurv.tiles.sources.Source
        The input, read for the coordinates.
    frame : heatcurv.choice.choices.CloudFrame
        The whole cloud's frame.
    sides : WindingSides
    alpha : float
        The run's ``alpha``: ball radius in spacings.
    flips : list
        The seam and winding flips so far (:func:`.output.chunk_flips`): a
        point's side is its record's turned by them.
    layer : float, optional
        The rays' noise layer, stages' units (:func:`heatcurv.orient.visibility.own_layer`).
    chunk : int, optional
        Rows read at a time.

    Returns
    -------
    report : dict
        ``turned`` (points the patch flips turn over), ``unsupported`` (points
        flagged) and ``escaped`` (points to turn to where their rays escape).
    rows : ndarray, shape (escaped,), int64
        Those points' input rows, sorted.
    """
    turned = unsupported = 0
    tree = cKDTree(sides.x)
    bad_tree = cKDTree(sides.x[sides.bad]) if sides.bad.any() and not sides.undecided else None
    tested = {"key": np.zeros(0, dtype=np.uint64), "row": np.zeros(0, dtype=np.int64), "x": np.zeros((0, 3)),
              "normals": np.zeros((0, 3))}
    for start, points, _ in source.chunks(chunk):
        block = read_results(results_path, start, start + len(points))
        computed = block["computed"] == 1
        kept = keyed_flips(block[sides.column], sides.keys, sides.open)  # open objects: not the field's sides
        flipped = keyed_flips(block[sides.column], sides.keys, sides.flip) ^ keyed_flips(
            block["winding_fine"], sides.fine_keys, sides.fine_flip)
        turned += int(np.sum(computed & ~kept & flipped))
        if sides.undecided:
            flagged = computed & ~(block["outlier"] == 1) & ~kept
        elif bad_tree is None:
            flagged = np.zeros(len(points), dtype=bool)
        else:
            flagged = _contradicted(block, points, start, frame, sides, tree, bad_tree, alpha)
        unsupported += int(flagged.sum())
        if flagged.any():
            rows = np.flatnonzero(flagged)
            changed = block[rows].copy()
            changed["reliable"] = 0
            write_records(results_path, changed, rows + start)
        rows = np.flatnonzero(computed & ~(block["outlier"] == 1) & ((block["reliable"] == 0) | flagged) & ~kept)
        x = frame.to_stage(points[rows])
        normals = block["normals"][rows]
        normals = np.where(chunk_flips(block, start, flips)[rows, None], -normals, normals)
        tested = _lowest({"key": row_hashes(x), "row": rows + start, "x": x, "normals": normals}, tested)
    occluder_normals = np.memmap(results_path, dtype=RECORD, mode="r")[sides.rows]["normals"]
    # the tested points are already those of lowest rank: their votes as escaping_turns reads them
    turn = escape_votes(tested["x"], tested["normals"], sides.x, occluder_normals, layer) < -TUNING.escape_margin
    rows = np.sort(tested["row"][turn])
    return {"turned": turned, "unsupported": unsupported, "escaped": int(rows.size)}, rows


def _lowest(new: dict, kept: dict) -> dict:
    """The entries of both sets (same keys of arrays, one ``key`` each) with the lowest
    :data:`heatcurv.orient.visibility.MAX_TESTED` keys."""
    both = {name: np.concatenate([kept[name], new[name]]) for name in kept}
    chosen = lowest_keys(both["key"], MAX_TESTED)
    return {name: value[chosen] for name, value in both.items()}


def _contradicted(block, points, start: int, frame, sides: WindingSides, tree: cKDTree, bad_tree: cKDTree,
                  alpha: float):
    """The rows of one chunk whose side the field contradicts (:func:`flag_unsupported`), shape (len(points),), bool."""
    computed = block["computed"] == 1
    x = frame.to_stage(points)
    # the operator ball, alpha h, a hair wider so that rounding keeps its farthest neighbour in
    radius = block["spacing"] / frame.unit * alpha * (1.0 + 1e-9)
    near = computed & ~(block["outlier"] == 1)
    flagged = np.zeros(len(points), dtype=bool)
    if near.any():
        total = tree.query_ball_point(x[near], radius[near], return_length=True)
        against = bad_tree.query_ball_point(x[near], radius[near], return_length=True)
        flagged[near] = against > 0.5 * total
        # a duplicate of a source (only one row of a set is) takes its flag
        distance, nearest = tree.query(x[near])
        twin = distance == 0.0
        flagged[np.flatnonzero(near)[twin]] = sides.bad[nearest[twin]]
    lo, hi = np.searchsorted(sides.rows, [start, start + len(points)])
    flagged[sides.rows[lo:hi] - start] = sides.bad[lo:hi]
    return flagged & computed
