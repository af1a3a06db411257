"""Every threshold that picks a fit path or flags a point, in one frozen object.

The estimator's stages compare their measurements against the fields of :data:`TUNING`
and against no number of their own: the noise gate and the kernel choice
(:mod:`heatcurv.choice.scale`), the fit plan (:mod:`heatcurv.choice.plan`), the anchors and their
carry (:mod:`heatcurv.fits.anchors`), the low-noise refit (:mod:`heatcurv.fits.chordfit`), the
orientation and its automatic policy (:mod:`heatcurv.orient.orientation`,
:mod:`heatcurv.orient.enclosure`), and the reliability flags (:mod:`heatcurv.flags.reliability`,
:mod:`heatcurv.flags.sheets`, :mod:`heatcurv.flags.outliers`, :mod:`heatcurv.flags.border`,
:mod:`heatcurv.choice.kernel_check`, :mod:`heatcurv.operators.areas`).

Each field carries a one-line reason (:func:`reasons`); the measurements behind the
values are in docs/how_it_works.md (thresholds). Sizes that only set how work is split
(blocks, samples, graph degrees) stay with the code that splits it, and so do the three
per-pair guards of the compiled carry (:mod:`heatcurv._kernels.anchors`), which numba
compiles into its cached machine code. Shares are fractions, noise levels are ``sigma``
over the median spacing (``info["scale"].relative_noise``) unless a field says otherwise.

A study of a threshold runs the stages with another value through
:func:`dataclasses.replace`; the estimator's own options stay in :mod:`heatcurv.options`.

>>> from heatcurv.tuning import TUNING, reasons
>>> TUNING.strong_noise
0.5
>>> reasons()["strong_noise"]
"noise above which the operator's balls are swamped and the anchors find their own normals"
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

__all__ = ["Tuning", "TUNING", "reasons"]


def _knob(value, reason: str):
    """A field of :class:`Tuning` with its default ``value`` and its one-line ``reason``."""
    return field(default=value, metadata={"reason": reason})


@dataclass(frozen=True)
class Tuning:
    """The thresholds of the default estimator; :data:`TUNING` holds the values it runs with."""

    # --- the noise gate and the kernel choice (heatcurv.choice.scale) ---
    #: Largest noise of a clean cloud, in spacings, beside the gate's residual ratio: strong noise saturates the
    #: chord residual (``|kN| <= 1 / |z|``) so the ratio alone cannot tell; clean clouds stay far below it.
    clean_noise_limit: float = _knob(0.01, "noise past which no cloud is clean, whatever the chord/denoised ratio")
    #: The chord fit's residual, in spacings, below which a cloud is exact (planar faces: float64 rounding,
    #: 1e-16 to 1e-15 near the origin, 2.5e-9 at coordinates of 4e6, a UTM northing), whatever the ratio of two
    #: such residuals; the rounding of coordinates written with 5-6 decimals is 1.5e-6 and is noise the denoised
    #: fit removes.
    exact_residual: float = _knob(1e-7, "chord residual (spacings) below which a cloud has nothing to denoise")
    #: Upper end of the very-low-noise band (:attr:`heatcurv.choice.scale.ScaleChoice.low_noise`): above the
    #: rounding of a LAZ file's millimetres and synthetic noise up to 1e-4 of the diagonal, below 0.12 % noise
    #: and the LiDAR tile.
    low_noise: float = _knob(0.02, "noise below which a widened kernel takes the very-low-noise path")
    #: Lower end of that band. Below it the noise is the rounding of fine coordinates (float32, text with 5-6
    #: decimals: 1.5e-6 to 7e-5), which the plain denoised fit at Lepski's width fits 2-4x better than the
    #: low-noise path, and in less time; the path wins from 7e-4 (synthetic noise of 1e-5 of the diagonal,
    #: 4 decimals). A cloud at rounding level (two planes at a fold: 1e-16) keeps the ordinary fit too.
    no_noise: float = _knob(1e-4, "noise below which a cloud's noise is fine rounding, outside the low-noise band")
    #: Doublings beyond Lepski's choice the very-low-noise path widens the kernel: the quartic refit has less bias
    #: than the plain denoised fit the rule compares; two doublings are too wide above 1e-5 of the diagonal.
    low_noise_levels: int = _knob(1, "doublings the very-low-noise refit widens the kernel beyond Lepski's choice")
    #: Candidates whose residual counts in the noise estimate, while each doubling raises the median residual by
    #: less than :attr:`noise_growth` (bias grows as ``R^2``, a factor 2 a doubling).
    noise_levels: int = _knob(4, "candidate widths whose residuals measure the noise")
    noise_growth: float = _knob(1.5, "rise of the residual per doubling below which it is still noise, not bias")
    #: A few per cent of vegetation or edges is no noisier surface: fitted as one, a LiDAR tile's tree crowns
    #: passed as reliable and a low-poly bone's coarser facets took a kernel too wide for its normals.
    min_region: float = _knob(0.25, "smallest share of the centres a noise region of its own must hold")
    tau_local: float = _knob(3.0, "standard deviations of a local bias before it narrows a region's kernel")
    #: A tiled run's halo must hold the widest candidate ball: twice the widest any of our noisy clouds chose.
    widest_kernel: int = _knob(15360, "widest candidate kernel (neighbours) on any cloud")

    # --- the fit plan and the anchors (heatcurv.choice.plan, heatcurv.fits.anchors) ---
    #: Between the noisiest clouds that orient fine on the operator's ``2 h`` balls (0.04-0.3) and a torus that
    #: did not (0.69: 21 % of its normals inward).
    strong_noise: float = _knob(0.5, "noise above which the operator's balls are swamped and the anchors find "
                                     "their own normals")
    #: Anchor spacing about ``R sqrt(pi / 16) = 0.44 R``.
    anchors_per_ball: int = _knob(16, "anchors per fitted ball of the anchored fit")
    #: Spacing about ``0.36 R``: dense enough for the regression of their tensors, within 4x the k-NN query.
    low_noise_anchors_per_ball: int = _knob(24, "anchors per fitted ball under very low noise")
    #: The refit's 15 unknowns are too many for 60 or 120 neighbours (torus at 1e-5, 60 neighbours: mean 1.80 %
    #: with the refit against 0.55 % without).
    low_noise_min_neighbours: int = _knob(240, "narrowest kernel the low-noise refit is fitted at")
    #: A 60-neighbour kernel's pair work is small, and small clouds keep their own fits.
    every_point: int = _knob(4, "kernels of at most this many times anchors_per_ball neighbours fit every point")
    #: The exact surface of a noisy model carries its noise non-linearly: the exact carry wins at moderate noise
    #: (sigma / R 0.004-0.011) and loses at strong noise (0.021-0.054).
    exact_carry_sigma: float = _knob(0.015, "anchor residual (ball radii) from which the carry is first-order")
    regression_degree: int = _knob(3, "degree of the regression of the anchors' tensors: cubic beat quadratic")
    #: ``lambda^2 = sigma / low_noise_sigma`` (both in ball radii) in the low-noise refit's pair weights.
    low_noise_sigma: float = _knob(6e-4, "residual scale of the low-noise refit's near-pair weights")
    #: Noisier centres keep the plain denoised height fit.
    low_noise_limit: float = _knob(4.0, "refit residual, in low_noise_sigma, up to which the refit is kept")
    #: Strong noise skips the refit: its residual would be the noise's.
    low_noise_tried: float = _knob(10.0, "height-fit residual, in refit limits, up to which the refit is tried")

    # --- orientation (heatcurv.orient.orientation, heatcurv.orient.enclosure) ---
    #: The LiDAR tile's tree crowns: median 0.52, 5 % under 0.34; its ground, roofs and walls: 0.08 % from 0.5.
    axisless_ball: float = _knob(0.5, "lambda_0 / lambda_1 from which up and viewpoint give a ball no normal axis")
    #: Such balls' fit residual over the cloud's noise: the LiDAR tiles' crowns 13-46 (5-50 %); saddles and
    #: paraboloids with noise of 0.6 and 1.2 % of their diagonal 1.1-1.7.
    axisless_residual: float = _knob(3.0, "fit residual, in noise sigmas, up to which an axisless ball is a surface")
    #: 72.5 degrees from the reference direction: a normal closer to perpendicular takes its neighbours' side.
    anchor_cosine: float = _knob(0.3, "|n . r| from which a normal's side is read off its reference direction")
    #: A wall takes about its half-height over the graph's edge length: a few to ten rounds on our LiDAR tiles.
    local_hops: int = _knob(32, "rounds of the local propagation of up and viewpoint; later points are ambiguous")
    conflict_in_plane: float = _knob(0.5, "|n . e| / |e| of a neighbour compared for a conflict (30 degrees)")
    conflict_aligned: float = _knob(0.7, "|n_i . n_j| of a neighbour compared for a conflict (45 degrees)")
    conflict_share: float = _knob(0.3, "share of compared neighbours facing the other way that flags a point")
    #: 2000-point samples: the LiDAR tile 92-93 %, a face range map from +z 66 %, street canyons 13-48 %, a
    #: tube 0 %; closed surfaces fail by facing down instead (auto_down_share).
    auto_share: float = _knob(0.1, "share of near-vertical sample normals from which orient='auto' may say up")
    #: Below it a face range map turned on its side passed along z on its few up-facing points (its sheet then
    #: 4.3 % in two minds) rather than along its own axis (0.15 %).
    auto_level_share: float = _knob(0.5, "near-vertical share from which z is preferred to the cloud's own axis")
    auto_vertical_cosine: float = _knob(math.sqrt(0.5), "|n_z| of a near-vertical normal (45 degrees)")
    #: Terrain and a face range map upright 0.0-0.2 %; a tilted face 1.1 %; closed surfaces 24-50 %.
    auto_down_share: float = _knob(0.005, "largest share of flat sample n_z facing down that still says up")
    #: Facades with 2 cm of noise: sample n_z within 0.05; a tilted face's chin, which must count, -0.1 to -0.3.
    auto_wall_cosine: float = _knob(0.1, "|n_z| of a flat sample normal from which its side counts as up or down")
    auto_flatness: float = _knob(0.15, "lambda_0 / lambda_1 of a flat sample point; tree crowns are not flat")
    #: 2000-point samples: the LiDAR tile 86-87 %, noisy open patches 65-100 %, a sphere with noise of 1.2 % of
    #: its diagonal 25 %; noise as thick as the sample's balls (3-5 % of the diagonal) 0.05-0.45 %.
    auto_flat_share: float = _knob(0.05, "least share of flat sample points from which orient='auto' may say up")
    #: How far from the median a sample centre's area may weigh in the auto policy's down share: a sphere sampled a
    #: hundred times more densely on top has 1 % of its centres below, which counted as points faced down by
    #: 0.49 % and made it terrain; a stray point's area, its nearest centres a diagonal away, would outweigh
    #: the surface.
    auto_area_range: float = _knob(4.0, "largest ratio of a sample centre's area to the median in the down share")
    #: A thin closed object lying flat is two sheets one over the other, which the sample's tree orients alike.
    auto_layered_share: float = _knob(0.1, "largest share of flat sample points with a sheet over them that says up")
    auto_layer_height: float = _knob(0.5, "least height of such a second sheet, in sample spacings")
    auto_layer_noise: float = _knob(3.0, "least height of such a second sheet, in units of the cloud's noise")
    #: Plates 1 x 1 x c: the faces 5 (c = 0.08) to 10 (c = 0.15) spacings apart; facades across a street 20 m wide 40.
    auto_layer_reach: float = _knob(12.0, "most height of such a second sheet, in sample spacings")
    #: Plates under about two spacings thick 42-77 %; noisy saddles, the LiDAR tile and a face range map 0-5 %.
    auto_split_share: float = _knob(0.25, "largest share of layered sample balls that still says up")
    auto_split_neighbours: int = _knob(30, "sample points in the balls auto_split_share reads (16 are too few)")
    #: A 4000-point lattice sphere whose sample keys left its equator empty: two hemispheres 6.1 spacings apart.
    auto_join_reach: float = _knob(10.0, "largest gap, in sample spacings, across which two sample trees are joined")
    auto_join_share: float = _knob(0.05, "least share of the sample in each of two trees that are joined")
    #: The switch between outward and the flat-patch convention is where a cloud and its half can differ:
    #: a turned LiDAR tile votes 0.12, its random half 0.07.
    weak_vote: float = _knob(0.03, "outward vote below which a component is too flat to tell inside from outside")
    #: Votes measured on the sample of surfaces over a plane turned away from horizontal: a face range map
    #: 0.92-0.94, a torus scanned from its side 1.0, a paraboloid 1.0; a LiDAR tile 0.03-0.07, a saddle 0.02.
    convex_vote: float = _knob(0.5, "outward vote of a surface over its own plane from which its convex side is up")
    #: Rays per side 19 (a vote moves by 1/19). CGAL's closed models, inside out on parts 3 spacings thick or more,
    #: pooled clean / noisy / half: none 1.74 / 1.87 / 3.56 %; margin 0.05: 1.32 / 1.51 / 2.15; 0.1: 1.26 / 1.41 /
    #: 2.08; 0.15: 1.26 / 1.41 / 2.15; 0.25: 1.30 / 1.45 / 2.24; 0.4: 1.48 % clean.
    escape_margin: float = _knob(0.15, "share of rays escaping more against than along its normal that turns a "
                                       "closed cloud's unreliable point")
    #: The rays clear a noise layer (:func:`heatcurv.orient.visibility.own_layer`) where the denoised residual at
    #: four times the narrowest kernel is at most this multiple of the narrowest's: noise leaves the same residual
    #: at every width, the misfit of a coarse mesh (which the choice reads as noise) grows as ``R^2``.
    noise_rise: float = _knob(1.4, "rise of the residual over two doublings of the kernel below which it is noise")
    tiny_patch: int = _knob(2, "pieces of fewer points join a neighbouring winding-number patch")
    level_tolerance: float = _knob(0.4, "distance of a winding level from its target that contradicts a side")
    sure_cost: float = _knob(0.7, "largest spanning-tree cost of an edge inside a winding-number patch")
    flip_margin: float = _knob(0.1, "energy per unit weight a patch's flip away from the tree must gain")
    spread_share: float = _knob(0.2, "share of disagreeing sources in a disc that flags its source too")
    #: A patch whose side is wrong keeps agreeing levels at some of its points (a face's folds, an armpit).
    patch_share: float = _knob(0.3, "share of a winding-number patch's area disagreeing that flags all of it")
    refine_share: float = _knob(0.1, "share of a winding-number patch's area disagreeing that re-cuts it finer")
    against_share: float = _knob(0.5, "share of a near point's sources that disagree before it is flagged too")
    #: An open sheet curved like a bowl has levels near 0 and 1/2.
    closed_share: float = _knob(0.3, "share of the area with clean winding levels from which a cloud is closed")
    closed_tolerance: float = _knob(0.25, "distance of a clean winding level from 0 or 1")
    #: Closed models a few points across their legs score between open scans and closed objects; what tells
    #: them from an open scene is their outside levels (outside_share).
    undecided_share: float = _knob(0.1, "clean-level share from which, below closed_share, a cloud is undecided")
    #: Median PCA roundness of the sources' balls: CGAL's coarse models (elk, dino, elephant at a quarter to a
    #: half of their vertices) 0.27-0.47; open clouds (terrain, a LiDAR tile, a face, graphs, an arch) 0.00-0.01.
    coarse_roundness: float = _knob(0.2, "median roundness of the winding sources' balls from which a cloud is "
                                         "coarse: undecided under undecided_share too")
    outside_share: float = _knob(0.5, "share of the area with outside levels near 0 that makes such a cloud "
                                      "undecided rather than open")
    #: CGAL's closed models, inside out and reliable, clean / noisy / half: 0.16 / 0.20 / 0.22 % without it;
    #: 0.0: 0.14 / 0.16 / 0.15; 0.3: 0.13 / 0.14 / 0.15; 0.6: 0.12 / 0.14 / 0.14 %, but 26 sources at a CAD
    #: part's sharp edges have cosines of 0.14-0.6 (none below 0): the normal's axis is off there, not its side.
    field_agreement: float = _knob(0.0, "cosine between a closed cloud's normal and the winding field's own below "
                                        "which its side is in doubt")
    #: Before the widths followed the roughness: 20 steps flagged within 0.01 points of 10, in twice the time.
    field_iterations: int = _knob(10, "steps of the winding field's own normals (heatcurv.orient.consistency)")
    #: Tori and spheres with noise of 0.12-0.6 % of their diagonal: 4 leaves 0.02-0.27 % of the field's normals
    #: over 53 degrees off, 6 none; CGAL's models flag as many at 8.
    field_roughness: float = _knob(6.0, "least narrowest width of the winding field's normals, in roughnesses")
    field_group_gap: float = _knob(0.5, "gap between two objects' boxes, in the smaller one's size, up to which "
                                        "their winding field is solved together")
    #: heatcurv.orient.consistency.split_sheets: surfaces passing through each other
    seam_tilt: float = _knob(0.2, "sine of the angle off each other's tangent plane within which two nearest "
                                  "sources are on one sheet")
    seam_parallel: float = _knob(0.9, "|cosine| of two sources' normals from which they are on one sheet")
    seam_along: float = _knob(0.99, "cosine of two sources' normals on one sheet from which they are one "
                                    "consistently oriented region")
    seam_pairs: int = _knob(3, "pairs of sources on one sheet facing opposite ways that join two regions "
                               "into one sheet with a seam")

    # --- reliability flags (heatcurv.flags.reliability, sheets, outliers, border, kernel_check, areas) ---
    planarity_min: float = _knob(0.05, "PCA planarity of a ball below which it is no surface patch")
    #: Smooth surfaces, noisy or not, stay within a few times the median; edges and tree crowns reach 10-450.
    misfit_factor: float = _knob(10.0, "chord residual over the cloud's median that is not one smooth surface")
    #: Where the residual is noise it is the same on every smooth part: 24 noisy analytic clouds at most 1.37 times
    #: their median, a torus whose noise grows twelvefold across it 2.25; a CAD part's sharp edges under noise of
    #: 0.02-0.05 mm 3-9, a LiDAR tile's roofs and walls about 10 (their values 0.08-0.16 / m off). Used where the
    #: quietest centres' residual is noise (:func:`heatcurv.choice.plan.noisy_residuals`).
    noise_misfit_factor: float = _knob(3.0, "fit residual over the cloud's median that is not one smooth surface, "
                                            "where the kernel choice measured noise")
    #: The kernel weighs a neighbour by its noisy distance, so the fitted heights flatten: a noisy sphere's mean
    #: curvature is off by about 15-30 (sigma / R)^2 with the kernel choice's sigma (12-18 with the true one; R the
    #: fit's ball radius), 1 % at 0.025 (the noise table's
    #: sphere), 8-11 % at 0.07-0.076, 17-25 % at 0.09-0.11; the noise table and held-out clouds at most 0.056
    #: (torus, 0.6 % noise: its error 5.3 %). Used where :attr:`FitPlan.flattening`.
    noise_flattening: float = _knob(0.07, "noise over the fit's ball radius from which the noise flattens the "
                                          "fitted curvature by about 10 %: not reliable")
    #: The small clouds the flag is for measure 0.30-0.63; CGAL's noisy camel (0.1 % noise, its coarse mesh's misfit
    #: doubling the residual) 0.17, where the flag would take 26 % of its points.
    flattening_noise: float = _knob(0.25, "noise, in spacings, from which the noise's flattening is flagged")
    #: The sphere's flattening is 12-18 (sigma / R)^2, a torus's and a cylinder's less and of either sign: 10 brings
    #: 10 of the error-bar benchmark's 62 clouds into its coverage band (7 without, 8 at 15, where the 0.6 %
    #: ellipsoid's bars grow too wide).
    flattening_bias: float = _knob(10.0, "the noise's flattening of a curvature, in (sigma / R)^2 of its value, that "
                                         "its standard error counts")
    misfit_floor: float = _knob(1e-3, "floor of the median residual (spacings) misfits are measured against")
    #: Fewer than about 12 points around an osculating circle: the balls wrap around the surface.
    resolution_limit: float = _knob(0.5, "median spacing in radii of curvature above which a cloud is unresolved")
    #: Tubes 2.5-3 spacings across 0.66-0.79; a tube 4 spacings across 0.32; CGAL's closed models at most 0.46.
    round_ball: float = _knob(0.65, "lambda_0 / lambda_1 of a ball that holds a tube, not a disc")
    precision_tolerance: float = _knob(0.01, "share of its curvature scale that rounding may move a reliable value")
    precision_coverage: float = _knob(5.0, "standard deviations of the rounding's error held against that tolerance")
    #: Bends the surface by 1.5 % of the ball's radius across it; below every clean accuracy cloud's curvature.
    flat_curvature: float = _knob(0.03, "floor of a point's curvature scale, in inverse fit radii")
    #: The inner third of the operator's 60-neighbour ball, where the fit's tapered weights are.
    sheet_neighbours: int = _knob(20, "nearest neighbours searched for the other side of a thin part")
    sheet_height: float = _knob(0.5, "least height over the tangent plane (spacings) of the other side")
    sheet_aligned: float = _knob(0.5, "-n_p . n_q above which two normals face away (within 60 degrees)")
    #: One sheet with normal noise stays above 2.3 in 9 of 10 balls of 60; plates 0.7-1.9 spacings thick 1.4-1.8.
    layer_kurtosis: float = _knob(2.0, "largest kurtosis of the quadric residuals of a ball split in two layers")
    layer_residual: float = _knob(0.15, "least quadric residual (spacings) of a layered ball; below it is rounding")
    layer_vote: float = _knob(0.5, "share of a point's sheet_neighbours that must be layered balls")
    sparse_factor: float = _knob(16.0, "density ratio between a point's scale and its ball's that makes it sparse")
    isolation_factor: float = _knob(3.0, "d_6 over its ball's median d_6 that isolates a point")
    ball_ratio_max: float = _knob(2.0, "ball radius over the neighbours' median that isolates a point")
    own_share: float = _knob(0.5, "least share of a ball in the point's own component; most of it strays")
    #: Well above an interior ball's offset, which shrinks as ``R / sqrt(k)``, and below a straight border's: its
    #: ball is a half disc, whose centroid lies ``4 R / (3 pi) = 0.42 R`` inside.
    border_offset: float = _knob(0.25, "centroid offset (ball radii) above which a point is on a border")
    #: The chord fit interpolates (2.4 effective neighbours: 0.13 % off), the tensor fit averages (5.4: 8 % off).
    chord_support: tuple = _knob((2.0, 3.0), "median effective neighbours of the chord fit below which it is an "
                                             "error, and a warning")
    tensor_support: tuple = _knob((5.0, 6.5), "median effective neighbours of the paper's tensor fit below which "
                                              "it is an error, and a warning")
    untapered_edge_weight: float = _knob(1e-3, "largest weight at a ball's edge (over the centre's) the paper's "
                                               "untapered quadratures take without a warning")
    tapered_edge_weight: float = _knob(math.exp(-1.0), "largest weight at a ball's edge (over the centre's) the "
                                                       "tapered chord fit takes without a warning")
    filled_share: float = _knob(0.9, "share of the points whose ball a radius an error suggests must fill")
    ball_area_factor_max: float = _knob(1.5, "largest correction of a ball's area for its curvature")


#: The thresholds the estimator runs with.
TUNING = Tuning()


def reasons() -> dict[str, str]:
    """The one-line reason of every field of :class:`Tuning`, by field name."""
    return {f.name: f.metadata["reason"] for f in fields(Tuning)}
