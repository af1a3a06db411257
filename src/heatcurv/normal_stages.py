"""The estimator's normals and orientation stages: which side every normal points to, and why.

:func:`orientation_mode` turns the ``orient`` option, given normals and a
viewpoint into one policy; :func:`normal_stages` runs the stages ``normals``
(PCA, or the given ones) and ``orientation`` (:mod:`heatcurv.orient.orientation`, ``"auto"``
decided first on the scale choice's sample); :func:`explained` says in the
report why the sides are what they are.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .choice.scale import centre_noise
from .errors import HeatcurvError
from .geometry.sampling import key_sample
from .geometry.validation import prepare_normals
from .operators.areas import fit_areas
from .operators.operator import HeatKernelOperator
from .orient.auto import auto_policy
from .orient.normals import pca_normals
from .orient.orientation import AutoPolicy, Orientation, OrientationReport, as_viewpoint, orient
from .progress import StageClock


def orientation_mode(orient_option: str, normals, viewpoint) -> str:
    """The orientation policy of this call: ``"given"``, ``"outward"``, ``"up"``, ``"viewpoint"``, or ``"auto"``.

    ``"auto"`` (no viewpoint, no normals) is decided on the cloud's sample by :func:`_auto_policy`.
    """
    if normals is not None:
        if viewpoint is not None:
            raise HeatcurvError("give either normals or a viewpoint, not both")
        if orient_option != "auto":
            raise HeatcurvError(f"orient={orient_option!r} orients estimated normals; the given normals are kept "
                                "as they are (leave orient='auto')")
        return "given"
    if orient_option == "auto":
        return "auto" if viewpoint is None else "viewpoint"
    if orient_option == "viewpoint" and viewpoint is None:
        raise HeatcurvError("orient='viewpoint' needs viewpoint=(x, y, z), the scanner's position")
    if orient_option != "viewpoint" and viewpoint is not None:
        raise HeatcurvError(f"a viewpoint orients the normals towards the scanner; it cannot be combined with "
                            f"orient={orient_option!r}")
    return orient_option


def _auto_policy(op: HeatKernelOperator, keys: np.ndarray, choices, normals: np.ndarray,
                 outlier: np.ndarray) -> AutoPolicy:
    """``orient="auto"`` without a viewpoint: ``"up"`` or ``"outward"``.

    :func:`heatcurv.orient.auto.auto_policy` decides.

    Decided on the scale choice's sample centres (the ``n_sub`` points of
    smallest keys) and the noise the choice measures there
    (:func:`heatcurv.choice.scale.centre_noise`: the same fit the choice makes
    next, on the unoriented ``normals``, shape (m, 3), with no weight on the
    ``outlier`` points, shape (m,), bool), or taken from ``choices`` (a tiled
    run's survey decided it on the same centres of the whole cloud, with the
    choice's ``sigma``).
    """
    if choices is not None and getattr(choices, "orientation", None) is not None:
        return choices.orientation
    opts = op.options
    tuning = opts.scale_tuning
    noise = centre_noise(op.points, op.tree, normals, fit_areas(op.areas, outlier), base_k=int(opts.neighbours),
                         alpha=opts.alpha, n_sub=tuning.n_sub, seed=tuning.seed, keys=keys, workers=opts.workers)
    return auto_policy(op.points[key_sample(keys, tuning.n_sub, tuning.seed)], noise)


def explained(report: OrientationReport, policy: AutoPolicy | None, n: int) -> OrientationReport:
    """``report`` with its reason (auto "up": and its convention).

    The reason is :attr:`~heatcurv.orient.orientation.OrientationReport.reason`.
    """
    if report.mode == "given":
        return replace(report, reason="the given normals, as they are")
    # balls without a normal axis (tree crowns, wires) take the reference direction itself
    axisless = (f"; {report.axisless} points whose ball has no normal axis (a tree crown, a wire, strong noise) "
                "start from it") if report.axisless else ""
    if report.mode == "viewpoint":
        return replace(report, reason="towards the viewpoint" + axisless)
    if report.mode == "up":
        if policy is None:
            return replace(report, reason="orient='up': towards +z" + axisless)
        # turning the cloud may change the choice (along +z, or along its own axis)
        return replace(report, reason=policy.reason + axisless, by_convention=n, policy=policy)
    if report.closed:
        why = "encloses a volume: away from it (winding number)"
    elif report.undecided:
        why = ("may or may not enclose a volume: the winding number's sides, every point flagged "
               "(too few points across its thin parts, or an open scene)")
    elif report.closed is None:
        why = "outward: each piece as the tree orients it (a part of a cloud)"
    else:
        why = "open: each component's outward vote, its convex side out"
        if report.by_convention and not report.upward_components:  # else by_convention counts those turned up
            why += "; nearly flat components by the least-variance-axis convention"
    if (report.closed or report.undecided) and report.open_components:
        why += (f"; {report.open_components} object(s) open on their own (a sheet beside the object): "
                "each its outward vote, its convex side out")
    if report.upward_components:
        why += f", but {report.upward_components} over the horizontal plane (terrain, ground): up (+z)"
    return replace(report, reason=why if policy is None else f"{policy.reason}; {why}", policy=policy)


def viewpoint_reference(op: HeatKernelOperator, mode: str, viewpoint):
    """What ``"viewpoint"`` orients towards, in the operator's (centred, distinct) frame; None otherwise."""
    if mode != "viewpoint":
        return None
    prepared = op.prepared
    v = as_viewpoint(viewpoint, prepared.n_input)
    return ((v if v.ndim == 1 else v[prepared.first]) - prepared.offset) / prepared.unit


def normal_stages(op: HeatKernelOperator, given, mode: str, towards, outlier: np.ndarray, clock: StageClock,
                   keys: np.ndarray, choices=None):
    """Stages ``normals`` and ``orientation``: oriented unit normals, the balls' PCA shape and the orientation.

    ``mode="auto"`` is decided first (:func:`_auto_policy`). Outliers get no
    weight in the outward vote (one far point would drag the centroid). Given
    ``choices`` (a part of a cloud), the winding number is not run here: the
    orientation's patches are cut for :mod:`heatcurv.tiles.winding`.

    Returns
    -------
    normals : ndarray, shape (m, 3)
    ball_shape : tuple of ndarray, shape (m,) each
        The balls' PCA planarity and roundness (:func:`heatcurv.orient.normals.pca_normals`; 1 and NaN
        for given normals).
    orientation : Orientation
    policy : AutoPolicy or None
        What ``"auto"`` chose, None for the other modes.
    """
    X, nbhd, prepared = op.points, op.neighbourhood, op.prepared
    if given is not None:
        with clock.stage("normals"):
            nrm = prepare_normals(given, prepared)
        kept = Orientation(nrm, np.zeros(X.shape[0], dtype=bool), OrientationReport("given"))
        return nrm, (np.ones(X.shape[0]), np.full(X.shape[0], np.nan)), kept, None
    with clock.stage("normals"):
        nrm, planarity, roundness = pca_normals(X, nbhd, taper=op.options.taper, roundness=True)
    with clock.stage("orientation"):
        policy = _auto_policy(op, keys, choices, nrm, outlier) if mode == "auto" else None
        if policy is not None and policy.towards is not None:
            towards = policy.towards
        orientation = orient(X, nrm, nbhd, op.areas, mode=mode if policy is None else policy.mode, towards=towards,
                             excluded=outlier, whole_cloud=choices is None,
                             cloud_points=None if choices is None else choices.frame.n_points, roundness=roundness,
                             open_up=policy is not None)
    return orientation.normals, (planarity, roundness), orientation, policy

