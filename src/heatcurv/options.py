"""Every option of the estimator, declared once: defaults, documentation, allowed values.

:class:`Options` is the single declaration. Each field carries, in its
``metadata``, the one-line help the command line shows, the allowed choices or
a range check, and the paper's equation where the paper has the parameter.
From it come

* the method presets :data:`METHODS` (``"default"`` and ``"paper"``);
* :func:`resolve_options`, which applies a caller's overrides to a preset and
  validates them (``heatcurv.estimate(**options)``, ``heatcurv.laplacian``);
* the command line's estimator flags (:mod:`heatcurv.cli.options`).

The tuning constants of the kernel choice (:mod:`heatcurv.scale`) are grouped in
:class:`ScaleTuning`, reachable as ``estimate(scale_tuning=ScaleTuning(...))``.

Public names use British spelling (``neighbours``); the American spellings
users type (``neighbors=``, ``min_neighbors=``) are accepted as deprecated
aliases (:data:`DEPRECATED_ALIASES`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from ._deprecation import renamed_keyword
from .errors import HeatcurvError

__all__ = [
    "Options", "ScaleTuning", "METHODS", "DEPRECATED_ALIASES", "resolve_options", "option_help", "rename_aliases",
]


def _positive(name: str, paper: str):
    """A check that ``value`` is a finite positive number."""

    def check(value):
        number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
        if not (number and math.isfinite(value) and value > 0):
            return f"{name} must be a positive number (paper: {paper}), got {value}"
        return None

    return check


def _unit_interval(name: str, paper: str):
    """A check that ``value`` is a number in ``[0, 1]``."""

    def check(value):
        number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
        if not (number and 0 <= value <= 1):
            return f"{name} must lie in [0, 1] (paper: {paper}), got {value!r}"
        return None

    return check


def _int_at_least(name: str, minimum: int, why: str = ""):
    """A check that ``value`` is a whole number ``>= minimum`` (``why`` says where the bound comes from)."""

    def check(value):
        number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
        if not (number and math.isfinite(value) and float(value).is_integer()):
            return f"{name} must be a whole number, got {value!r}"
        if value < minimum:
            return f"{name} must be at least {minimum}{why}, got {value}"
        return None

    return check


def _workers(value):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not (value == -1 or value >= 1):
        return f"workers must be -1 (all cores) or a thread count >= 1, got {value!r}"
    return None


def _optional_positive(name: str):
    """A check that ``value`` is None or a finite positive number."""
    positive = _positive(name, "")

    def check(value):
        if value is None:
            return None
        problem = positive(value)
        return None if problem is None else f"{name} must be a positive length (or None), got {value}"

    return check


def _option(
    default, help: str, *, choices=None, check=None, paper: str = "", cli: bool = True, type=None  # noqa: A002
):
    """A dataclass field of :class:`Options` with its documentation and validation.

    Parameters
    ----------
    default
        The value of the ``"default"`` method.
    help : str
        One line: what the option does, its range, its paper value.
    choices : tuple, optional
        The allowed values of a categorical option.
    check : callable, optional
        ``check(value) -> str | None``: an error message for a bad value.
    paper : str, optional
        The paper's equation or section that defines the parameter.
    cli : bool, optional
        Whether the command line exposes it as ``--name``.
    type : type, optional
        The value's type where the default (None) does not show it.
    """
    meta = {"help": help, "choices": choices, "check": check, "paper": paper, "cli": cli, "type": type}
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class ScaleTuning:
    """Tuning constants of the automatic kernel choice (:func:`heatcurv.scale.select_scale`).

    Attributes
    ----------
    k_fit : int
        Widest kernel (neighbours) fitted against every point; wider kernels
        are fitted against a random coarser level holding about ``k_fit``
        points per ball (240).
    n_sub : int
        Points the candidate kernels are compared on (2000).
    tau : float
        Lepski's tolerance: the largest median change between candidates, in
        standard deviations of the narrower one (1.0; pure noise gives 0.67).
    clean_ratio : float
        A cloud is clean when the chord fit's residual is at most this multiple
        of the denoised fit's (1.6; measured 0.2-1.3 clean, 2.2-4.4 noisy).
    max_k : int or None
        Widest candidate kernel; None: a tenth of the cloud, at least 1920.
    seed : int
        Seed of the subsample and the coarse levels (results are reproducible).
    """

    k_fit: int = 240
    n_sub: int = 2000
    tau: float = 1.0
    clean_ratio: float = 1.6
    max_k: int | None = None
    seed: int = 0

    def check(self) -> str | None:
        """An error message if a constant is out of range, else None."""
        if int(self.k_fit) < 20:
            return f"scale_tuning.k_fit must be at least 20, got {self.k_fit}"
        if int(self.n_sub) < 10:
            return f"scale_tuning.n_sub must be at least 10, got {self.n_sub}"
        if not (math.isfinite(self.tau) and self.tau > 0):
            return f"scale_tuning.tau must be a positive number, got {self.tau}"
        if not (math.isfinite(self.clean_ratio) and self.clean_ratio > 0):
            return f"scale_tuning.clean_ratio must be a positive number, got {self.clean_ratio}"
        if self.max_k is not None and int(self.max_k) < 20:
            return f"scale_tuning.max_k must be at least 20 or None, got {self.max_k}"
        return None


def _check_scale(value):
    if value == "auto" or (isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 20):
        return None
    return f"scale must be 'auto' or a neighbour count of at least 20, got {value!r}"


def _check_tuning(value):
    if not isinstance(value, ScaleTuning):
        return f"scale_tuning must be a heatcurv.options.ScaleTuning, got {type(value).__name__}"
    return value.check()


@dataclass(frozen=True)
class Options:
    """Every knob of the pipeline, with the paper's names where the paper has one.

    The ``"default"`` values are those below; :data:`METHODS` holds the
    ``"paper"`` preset. Each field's ``metadata["help"]`` is its documentation
    (also the command line's ``--help``); :func:`option_help` lists them.

    Attributes
    ----------
    method : str
        Name of the preset the other values came from.
    alpha : float
        Ball radius in units of the spacing, ``r = alpha h`` (paper: 3.5-4.5).
    m : float
        Diffusion-time constant, ``t = m h^2`` (eq 2.8; paper: 1/4).
    spacing : {"global", "local", "density"}
        ``h`` from eq 2.6 (one value), eq 2.7 (per point), or the density
        radius ``d_k / alpha`` with ``k = neighbours``.
    gamma : float
        Blend of eq 2.7 (paper: 0.1-0.5).
    k_local : int
        Nearest neighbours the min/max of eq 2.7 run over.
    neighbours : int
        Neighbours in the ball of the density spacing, and the narrowest
        kernel of the chord fit.
    radius : float or None
        One ball radius for every point, in the cloud's length unit (as PCL's
        or CloudCompare's radius), instead of a neighbour count: the operator
        and the chord fit use the ball of this radius, ``h = radius / alpha``.
        Points whose ball holds fewer than ``min_neighbours`` get their
        nearest ones (and are unreliable). None: the ball holds ``neighbours``
        points (density spacing) and the fit's kernel is chosen from the noise.
    area_method : {"system", "density"}
        Areas from the paper's ``H A = 1`` (section 2.2) or from the
        flat-top density estimate (:func:`heatcurv.areas.density_areas`).
    mean_formula : {"norm", "projection"}
        Mean curvature as ``1/2 |K|`` signed (eq 2.11) or ``1/2 K . n`` (eq 2.12),
        for the fits that take it from the quadrature.
    fit : {"constrained", "unconstrained", "chord"}
        Principal fit with the constraints of eq 3.1, free, or the chord fit
        with tilt and cubic terms (:mod:`heatcurv.chordfit`).
    scale : "auto" or int
        Kernel of the chord fit: ``"auto"`` chooses it from the measured noise
        (:mod:`heatcurv.scale`); an integer ``k`` fixes it to ``k`` neighbours.
    scale_tuning : ScaleTuning
        Constants of the automatic kernel choice.
    orient : {"auto", "outward", "up", "viewpoint"}
        Which side the estimated normals point to (:mod:`heatcurv.orientation`):
        away from the enclosed volume, towards +z, or towards the scanner
        (``estimate(viewpoint=...)``); ``"auto"`` is ``"viewpoint"`` when a
        viewpoint is given, else ``"outward"``.
    area_solver : {"auto", "cg", "bicgstab", "direct"}
        Solver of ``H A = 1``.
    taper : bool
        Weight the PCA and the border test by a flat-top taper that falls to
        0 at the ball's edge (:func:`heatcurv.kernel.ball_taper`), so results
        are continuous in the points; False is the paper's plain PCA.
    min_neighbours : int
        Fewest neighbours a point may have; sparser points get their nearest ones.
    workers : int
        Threads for the k-d tree queries and the compiled kernels (-1: all
        cores; 1: one thread, e.g. when the caller parallelises over clouds).
    """

    method: str = _option("default", "preset the other options start from", cli=False)
    alpha: float = _option(
        2.0, "ball radius r = alpha h in units of the spacing (paper's range 3.5-4.5)",
        check=_positive("alpha", "3.5-4.5"), paper="section 2, alpha 3.5-4.5",
    )
    m: float = _option(
        0.25, "diffusion time t = m h^2 (eq 2.8)", check=_positive("m", "1/4"), paper="eq 2.8"
    )
    spacing: str = _option(
        "density", "spacing h: global mean NN distance (eq 2.6), local blend (eq 2.7), or density (d_k / alpha)",
        choices=("global", "local", "density"), paper="eq 2.6, 2.7",
    )
    gamma: float = _option(
        0.25, "blend of the local spacing, eq 2.7 (0..1)",
        check=_unit_interval("gamma", "0.1-0.5"),
        paper="eq 2.7",
    )
    k_local: int = _option(
        8, "neighbours of the local spacing's min/max (eq 2.7)", check=_int_at_least("k_local", 2), paper="eq 2.7"
    )
    neighbours: int = _option(
        60, "neighbours in the density ball, and the narrowest kernel of the chord fit",
        check=_int_at_least("neighbours", 20, " (the chord fit has 9 unknowns)"),
    )
    radius: float | None = _option(
        None, "one ball radius for every point, in the cloud's length unit, instead of a neighbour count "
        "(the fit's kernel then does not adapt to the noise)", check=_optional_positive("radius"), type=float,
    )
    area_method: str = _option(
        "density", "per-point areas: paper's H A = 1 (system) or density estimate", choices=("system", "density"),
        paper="section 2.2",
    )
    mean_formula: str = _option(
        "projection", "mean curvature from K: 1/2|K| (norm, eq 2.11) or 1/2 K.n (projection, eq 2.12)",
        choices=("norm", "projection"), paper="eq 2.11, 2.12",
    )
    fit: str = _option(
        "chord", "principal fit: chord (default), constrained (eq 3.1) or unconstrained",
        choices=("constrained", "unconstrained", "chord"), paper="section 3, eq 3.1",
    )
    scale: object = _option(
        "auto", "kernel of the chord fit: auto (from the measured noise) or a neighbour count >= 20",
        check=_check_scale,
    )
    scale_tuning: ScaleTuning = _option(ScaleTuning(), "constants of the automatic kernel choice", check=_check_tuning,
                                        cli=False)
    orient: str = _option(
        "auto", "which side the normals point to: outward (closed objects), up (+z: terrain, buildings, aerial "
        "LiDAR), viewpoint (towards the scanner); auto: viewpoint when one is given, else outward "
        "(the command line: up for LAS/LAZ)",
        choices=("auto", "outward", "up", "viewpoint"),
    )
    area_solver: str = _option(
        "auto", "solver of H A = 1 (area_method system)", choices=("auto", "cg", "bicgstab", "direct"),
    )
    taper: bool = _option(True, "taper the PCA and border weights to 0 at the ball's edge", cli=False)
    min_neighbours: int = _option(
        6, "fewest neighbours per point; sparser points get their nearest ones",
        check=_int_at_least("min_neighbours", 3, " (the tensor fit has 3 unknowns)"),
    )
    workers: int = _option(
        -1, "threads for the k-d tree and the compiled kernels (-1: all cores)", check=_workers, cli=False
    )


#: The presets of ``method=``.
#:
#: ``"paper"`` follows the paper literally and is the reproducible reference:
#: eq 2.6 spacing, ``alpha = 4``, ``m = 1/4``, areas from ``H A = 1``, mean
#: curvature ``1/2 |K|`` (eq 2.11), the constrained fit of eq 3.1.
#:
#: ``"default"`` replaces the stages that fail on irregular and noisy clouds,
#: each by a named option: spacing from density (``spacing="density"``, the
#: ball holds 60 neighbours, ``alpha = 2``), areas from a density estimate
#: (``area_method="density"``), and the chord fit with tilt and cubic terms at
#: a noise-adapted kernel (``fit="chord"``, ``scale="auto"``). The heat kernel
#: (``t = h^2/4``, eq 2.8) weights the fit, and the mean-curvature normal of
#: eq 2.10 is still computed (``result.mean_curvature_normal``, used by the
#: feature detector).
METHODS: dict[str, Options] = {
    "paper": Options(
        method="paper", alpha=4.0, spacing="global", area_method="system", mean_formula="norm",
        fit="constrained", scale=None, taper=False,
    ),
    "default": Options(method="default"),
}

#: American spellings users type, accepted with a DeprecationWarning: alias -> name.
DEPRECATED_ALIASES = {"neighbors": "neighbours", "min_neighbors": "min_neighbours"}


def rename_aliases(kwargs: dict, where: str = "heatcurv", stacklevel: int = 3) -> dict:
    """``kwargs`` with deprecated aliases (``neighbors=``) renamed (``neighbours=``), warning once each.

    Raises
    ------
    HeatcurvError
        When both spellings are given.
    """
    out = dict(kwargs)
    for alias, name in DEPRECATED_ALIASES.items():
        if alias in out:
            out[name] = renamed_keyword(where, name, out.get(name), alias, out.pop(alias), stacklevel=stacklevel + 1)
    return out


def option_help() -> dict[str, str]:
    """The one-line documentation of every option, by name (the command line's help)."""
    return {f.name: f.metadata["help"] for f in fields(Options)}


def resolve_options(method: str = "default", **overrides) -> Options:
    """The preset ``method`` with the non-None ``overrides`` applied, validated.

    Parameters
    ----------
    method : {"default", "paper"}
        The preset (:data:`METHODS`).
    **overrides
        Any :class:`Options` field; None leaves the preset's value. The
        deprecated aliases ``neighbors`` and ``min_neighbors`` are accepted.

    Returns
    -------
    Options

    Raises
    ------
    HeatcurvError
        On an unknown method, option or choice, or a value out of range.
    """
    if method not in METHODS:
        raise HeatcurvError(f"unknown method {method!r}; choose one of {', '.join(sorted(METHODS))}")
    given = {k: v for k, v in rename_aliases(overrides).items() if v is not None}
    unknown = set(given) - {f.name for f in fields(Options)}
    if unknown:
        raise HeatcurvError(f"unknown option(s) {', '.join(sorted(unknown))}")
    opts = replace(METHODS[method], **given)
    if opts.fit == "chord" and opts.scale is None:
        opts = replace(opts, scale="auto")
    for f in fields(Options):
        value, meta = getattr(opts, f.name), f.metadata
        if f.name == "scale" and opts.fit != "chord":
            continue  # the paper's fits have no kernel choice
        if meta.get("choices") is not None and value not in meta["choices"]:
            raise HeatcurvError(f"{f.name} must be one of {', '.join(map(repr, meta['choices']))}, got {value!r}")
        if meta.get("check") is not None:
            problem = meta["check"](value)
            if problem is not None:
                raise HeatcurvError(problem)
    return opts
