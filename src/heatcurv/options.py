"""Every option of the estimator, declared once: defaults, documentation, allowed values.

:class:`Options` is the single declaration. Each field carries, in its
``metadata``, the one-line help the command line shows, the allowed choices or
a range check, and the paper's equation where the paper has the parameter.
From it come

* the method presets :data:`METHODS` (``"default"`` and ``"paper"``);
* :func:`resolve_options`, which applies a caller's overrides to a preset and
  validates them (``heatcurv.estimate(**options)``, ``heatcurv.laplacian``);
* the command line's estimator flags (:mod:`heatcurv.cli.options`).

The tuning constants of the kernel choice (:mod:`heatcurv.choice.scale`) are grouped in
:class:`ScaleTuning`, reachable as ``estimate(scale_tuning=ScaleTuning(...))``.

Names use British spelling (``neighbours``); an unknown option, such as the
American ``neighbors=``, is an error that names the option meant.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from .errors import HeatcurvError

__all__ = [
    "Options", "ScaleTuning", "METHODS", "RANGES", "Range", "resolve_options", "option_help", "range_problem",
    "check_options_for_cloud", "SEED_RANGE", "workers_problem",
]


@dataclass(frozen=True)
class Range:
    """The documented range of a numeric option, and why.

    Attributes
    ----------
    low, high : float
        The smallest and largest accepted value (both included).
    integer : bool
        Whether the value must be a whole number.
    why : str
        The reason for the range, printed with a refused value.
    """

    low: float
    high: float
    integer: bool
    why: str
    shown: str = ""

    def describe(self) -> str:
        """``[low, high]`` (or ``shown``, where the range has a gap)."""
        return self.shown or f"[{_show(self.low)}, {_show(self.high)}]"


def _show(value) -> str:
    """A number as the messages print it: ``1e+09``, ``0.25``, ``60``, ``1e+30`` (anything else: its repr)."""
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if not isinstance(value, (int, float, np.integer, np.floating)):
        return repr(value)
    if isinstance(value, (int, np.integer)) and abs(int(value)) < 10**15:
        return str(int(value))
    return f"{float(value):g}"


def _is_number(value) -> bool:
    """A real number of a numeric type (booleans are not)."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


#: numpy's random generators take a non-negative 64-bit seed (every ``seed`` option and flag).
SEED_RANGE = Range(0, 2**63 - 1, True, "numpy's random generators take a non-negative 64-bit seed")


def _got(value) -> str:
    """A refused value of the wrong kind as the messages print it: ``2.0``, ``nan``, ``True``, ``'many'``."""
    return repr(float(value)) if isinstance(value, (float, np.floating)) else _show(value)


#: The documented range of every numeric option of :class:`Options` and
#: :class:`ScaleTuning`, by name (``scale_tuning.<field>`` for the latter).
#: Measured on a 2000-point random unit sphere
#: (``heatcurv.surfaces.Sphere().sample(2000, "random")``) and on the Fibonacci
#: sphere of the ``"paper"`` method; the limits that depend on the cloud (the
#: number of its points, its size) are :func:`check_options_for_cloud`'s.
RANGES: dict[str, Range] = {
    "alpha": Range(
        0.5, 20.0, False,
        "the ball's radius in spacings: below 0.5 the kernel is wider than its ball, above 20 a ball holds "
        "over a thousand neighbours (the paper uses 3.5-4.5)",
    ),
    "m": Range(
        1e-3, 10.0, False,
        "t = m h^2: below 1e-3 no neighbour has weight (1e-300 gave NaN), above 10 the kernel is flat over "
        "its ball (the paper uses 1/4)",
    ),
    "gamma": Range(0.0, 1.0, False, "a blend of two spacings, eq 2.7 (the paper uses 0.1-0.5)"),
    "k_local": Range(
        2, 1000, True, "the local spacing's min and max need 2 neighbours; more than 1000 is the global spacing",
    ),
    "neighbours": Range(
        20, 1920, True,
        "the chord fit has 9 unknowns; 1920 is its widest default kernel (and 2e9 pairs on a million points)",
    ),
    "min_neighbours": Range(
        3, 1920, True, "the tensor fit has 3 unknowns; 1920 is the widest neighbour count",
    ),
    "scale": Range(
        20, 1_000_000, True,
        "the chord fit has 9 unknowns; 1e6 is the automatic choice's widest kernel on 10 million points",
    ),
    "workers": Range(
        -1, 1024, True, "-1 is all cores; more than 1024 threads exceeds any machine's cores",
        shown="-1 or [1, 1024]",
    ),
    "scale_tuning.k_fit": Range(20, 1920, True, "a fitted kernel, as neighbours"),
    "scale_tuning.n_sub": Range(
        10, 1_000_000, True, "a median over fewer than 10 points means nothing; 1e6 fits a large cloud whole",
    ),
    "scale_tuning.tau": Range(
        1e-6, 100.0, False,
        "a tolerance in standard deviations (pure noise: 0.67); 1e-6 already refuses every wider kernel, "
        "100 accepts every one",
    ),
    "scale_tuning.clean_ratio": Range(
        0.1, 10.0, False,
        "measured 0-2.0 on clean and 2.2-4.0 on noisy clouds: beyond, every cloud is noisy or every one clean",
    ),
    "scale_tuning.max_k": Range(20, 1_000_000, True, "the widest candidate kernel, as scale (or None)"),
    "scale_tuning.seed": SEED_RANGE,
}


def range_problem(name: str, value, limits: Range | None = None) -> str | None:
    """An error message if ``value`` is not a number in option ``name``'s range, else None.

    NaN, infinities, booleans and strings are refused; a whole number is
    needed where ``limits.integer`` (``40.0`` is accepted as 40, ``40.5`` not).
    The message is one line: ``alpha = 1e+09 is outside its range [0.5, 20]: <why>``.
    """
    limits = RANGES[name] if limits is None else limits
    kind = "a whole number" if limits.integer else "a number"
    if not _is_number(value) or not math.isfinite(value) or (limits.integer and not float(value).is_integer()):
        return f"{name} must be {kind} in {limits.describe()}, got {_got(value)}"
    if not limits.low <= value <= limits.high:
        return f"{name} = {_show(value)} is outside its range {limits.describe()}: {limits.why}"
    return None


def _in_range(name: str):
    """The check of option ``name``: its value within :data:`RANGES`."""

    def check(value):
        return range_problem(name, value)

    return check


def workers_problem(value) -> str | None:
    """What is wrong with a ``workers`` value (-1, all cores, or a thread count in [1, 1024]), or None."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        return f"workers must be -1 (all cores) or a whole thread count in [1, 1024], got {_got(value)}"
    if value == 0:
        return f"workers = 0 is outside its range {RANGES['workers'].describe()}: {RANGES['workers'].why}"
    return range_problem("workers", value)


def _optional_positive(name: str):
    """A check that ``value`` is None or a finite positive number (a length: its bounds are the cloud's)."""

    def check(value):
        if value is None:
            return None
        if not (_is_number(value) and math.isfinite(value) and value > 0):
            return f"{name} must be a positive length (or None), got {_got(value)}"
        return None

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
    """Tuning constants of the automatic kernel choice (:func:`heatcurv.choice.scale.select_scale`).

    Attributes
    ----------
    k_fit : int
        Widest kernel (neighbours) of a clean cloud fitted at every point;
        wider kernels, and every kernel of a noisy cloud, are fitted at anchors
        with all the points of their balls and carried to every point
        (:mod:`heatcurv.fits.anchors`) (240).
    n_sub : int
        Points the candidate kernels are compared on (2000).
    tau : float
        Lepski's tolerance: the largest median change between candidates, in
        standard deviations of the narrower one (1.0; pure noise gives 0.67).
    clean_ratio : float
        A cloud is clean when the chord fit's residual is at most this multiple
        of the denoised fit's (2.2; measured 0-2.0 clean, 2.2-4.0 noisy).
    max_k : int or None
        Widest candidate kernel; None: a quarter of the cloud, at most
        ``TUNING.widest_kernel``.
    seed : int
        Seed of the subsample and the anchors (results are reproducible).
    """

    k_fit: int = 240
    n_sub: int = 2000
    tau: float = 1.0
    clean_ratio: float = 2.2
    max_k: int | None = None
    seed: int = 0

    def check(self) -> str | None:
        """An error message if a constant is out of its range (:data:`RANGES`), else None."""
        for name in ("k_fit", "n_sub", "tau", "clean_ratio", "max_k", "seed"):
            value = getattr(self, name)
            if name == "max_k" and value is None:
                continue
            problem = range_problem(f"scale_tuning.{name}", value)
            if problem is not None:
                return problem
        return None


def _check_scale(value):
    if value == "auto":
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        return f"scale must be 'auto' or a neighbour count in {RANGES['scale'].describe()}, got {_got(value)}"
    return range_problem("scale", value)


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
        nearest ones (and are unreliable); a radius whose median ball holds
        fewer points than the fit needs warns and names one that holds enough
        (:func:`heatcurv.choice.kernel_check.check_ball_counts`). None: the ball holds ``neighbours``
        points (density spacing) and the fit's kernel is chosen from the noise.
    area_method : {"system", "density"}
        Areas from the paper's ``H A = 1`` (section 2.2) or from the
        flat-top density estimate (:func:`heatcurv.operators.areas.density_areas`).
    mean_formula : {"norm", "projection"}
        Mean curvature as ``1/2 |K|`` signed (eq 2.11) or ``1/2 K . n`` (eq 2.12),
        for the fits that take it from the quadrature.
    fit : {"constrained", "unconstrained", "chord"}
        Principal fit with the constraints of eq 3.1, free, or the chord fit
        with tilt and cubic terms (:mod:`heatcurv.fits.chordfit`).
    scale : "auto" or int
        Kernel of the chord fit: ``"auto"`` chooses it from the measured noise
        (:mod:`heatcurv.choice.scale`); an integer ``k`` fixes it to ``k`` neighbours.
    scale_tuning : ScaleTuning
        Constants of the automatic kernel choice.
    orient : {"auto", "outward", "up", "viewpoint"}
        Which side the estimated normals point to (:mod:`heatcurv.orient.orientation`):
        away from the enclosed volume, towards +z, or towards the scanner
        (``estimate(viewpoint=...)``); ``"auto"`` is ``"viewpoint"`` when a
        viewpoint is given, else ``"up"`` for an open surface over the
        horizontal plane (terrain, roofs), the same along its own axis for an
        open surface over another plane, and ``"outward"`` for anything else
        (:func:`heatcurv.orient.auto.auto_policy`;
        ``info["orientation"].reason`` says which).
    area_solver : {"auto", "cg", "bicgstab", "direct"}
        Solver of ``H A = 1``.
    taper : bool
        Weight the PCA and the border test by a flat-top taper that falls to
        0 at the ball's edge (:func:`heatcurv.operators.kernel.ball_taper`), so results
        are continuous in the points; False is the paper's plain PCA.
    min_neighbours : int
        Fewest neighbours a point may have; sparser points get their nearest ones.
    workers : int
        Threads for the k-d tree queries and the compiled kernels (-1: all
        cores; 1: one thread, e.g. when the caller parallelises over clouds).
    se : bool
        Standard errors of the chord fit's curvatures and normals
        (``CurvatureResult.mean_se`` ..., :mod:`heatcurv.fits.uncertainty`); False
        skips their extra fits at sample centres.

    Notes
    -----
    Every numeric option has a documented range (:data:`RANGES`, with the
    reason each bound is there); :func:`resolve_options` refuses a value
    outside it, NaN, infinities, booleans and, where a count is needed,
    non-integers, with one line naming the option, its value and the range.
    Measured on a 2000-point random unit sphere (and the paper's Fibonacci
    sphere for ``m``):

    =========================  ==================  ============================================
    option                     range               why
    =========================  ==================  ============================================
    ``alpha``                  0.5 - 20            below: kernel wider than its ball; above:
                                                   1000+ neighbours per ball, a small cloud's
                                                   balls cover it (alpha 40: mean curvature 0)
    ``m``                      0.001 - 10          below: no neighbour weighs (m = 1e-300: NaN);
                                                   above: flat kernel, ``H A = 1`` diverges
    ``gamma``                  0 - 1               a blend (eq 2.7)
    ``k_local``                2 - 1000 (integer)  a min and a max; memory
    ``neighbours``             20 - 1920 (integer) 9 unknowns of the chord fit; the kernel
                                                   ladder's widest default candidate (1921 gave
                                                   IndexError on 2000 points); memory
    ``min_neighbours``         3 - 1920 (integer)  3 unknowns of the tensor fit
    ``scale``                  20 - 10^6 (integer) as ``neighbours``; 10^6: the ladder's widest
                                                   kernel on 10 million points
    ``radius``                 > 0                 a length: bounded by the cloud (below)
    ``workers``                -1 or 1 - 1024      all cores, or a thread count
    ``scale_tuning.k_fit``     20 - 1920           as ``neighbours``
    ``scale_tuning.n_sub``     10 - 10^6           a median over the subsample
    ``scale_tuning.tau``       1e-6 - 100          beyond: no widening / every widening
    ``scale_tuning.clean_ratio`` 0.1 - 10          measured 0-2.0 clean, 2.2-4.0 noisy
    ``scale_tuning.max_k``     20 - 10^6 or None   as ``scale``; at least ``neighbours``
    ``scale_tuning.seed``      0 - 2^63-1          numpy's seeds
    =========================  ==================  ============================================

    The limits that depend on the cloud are :func:`check_options_for_cloud`'s:
    ``neighbours``, ``scale`` and ``min_neighbours`` at most the number of
    distinct points minus 2 (at least one point outside every ball),
    ``k_local`` below the number of distinct points, and ``radius`` at most
    half the bounding-box diagonal (a larger ball around the cloud's centre
    holds all of it; a unit sphere's mean curvature came out with the wrong
    sign at radius 2.5) and at least ``1e-9`` of it (smaller balls hold no
    neighbour and the kernel ``t = m (radius / alpha)^2`` underflows).
    """

    method: str = _option("default", "preset the other options start from", cli=False)
    alpha: float = _option(
        2.0, "ball radius r = alpha h in units of the spacing, 0.5-20 (paper's range 3.5-4.5)",
        check=_in_range("alpha"), paper="section 2, alpha 3.5-4.5",
    )
    m: float = _option(
        0.25, "diffusion time t = m h^2 (eq 2.8), 0.001-10", check=_in_range("m"), paper="eq 2.8"
    )
    spacing: str = _option(
        "density", "spacing h: global mean NN distance (eq 2.6), local blend (eq 2.7), or density (d_k / alpha)",
        choices=("global", "local", "density"), paper="eq 2.6, 2.7",
    )
    gamma: float = _option(
        0.25, "blend of the local spacing, eq 2.7, 0-1",
        check=_in_range("gamma"),
        paper="eq 2.7",
    )
    k_local: int = _option(
        8, "neighbours of the local spacing's min/max (eq 2.7), 2-1000", check=_in_range("k_local"), paper="eq 2.7"
    )
    neighbours: int = _option(
        60, "neighbours in the density ball, and the narrowest kernel of the chord fit, 20-1920",
        check=_in_range("neighbours"),
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
        "auto", "kernel of the chord fit: auto (from the measured noise) or a neighbour count, 20-1000000",
        check=_check_scale,
    )
    scale_tuning: ScaleTuning = _option(ScaleTuning(), "constants of the automatic kernel choice", check=_check_tuning,
                                        cli=False)
    orient: str = _option(
        "auto", "which side the normals point to: outward (closed objects), up (+z: terrain, buildings, aerial "
        "LiDAR), viewpoint (towards the scanner); auto: viewpoint when one is given, else up for an open "
        "surface over the horizontal plane and outward for anything else (the command line: up for LAS/LAZ)",
        choices=("auto", "outward", "up", "viewpoint"),
    )
    area_solver: str = _option(
        "auto", "solver of H A = 1 (area_method system)", choices=("auto", "cg", "bicgstab", "direct"),
    )
    taper: bool = _option(True, "taper the PCA and border weights to 0 at the ball's edge", cli=False)
    min_neighbours: int = _option(
        6, "fewest neighbours per point, 3-1920; sparser points get their nearest ones",
        check=_in_range("min_neighbours"),
    )
    workers: int = _option(
        -1, "threads for the k-d tree and the compiled kernels: -1 (all cores) or 1-1024", check=workers_problem,
        cli=False,
    )
    se: bool = _option(True, "standard errors of the curvatures and normals (the chord fit)", choices=(True, False),
                       cli=False)


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
        Any :class:`Options` field; None leaves the preset's value.

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
    given = {k: v for k, v in overrides.items() if v is not None}
    names = [f.name for f in fields(Options)]
    unknown = sorted(set(given) - set(names))
    if unknown:
        raise HeatcurvError(f"unknown option(s) {', '.join(_with_suggestion(name, names) for name in unknown)}")
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
    max_k = opts.scale_tuning.max_k
    if opts.fit == "chord" and opts.radius is None and max_k is not None and max_k < opts.neighbours:
        raise HeatcurvError(
            f"scale_tuning.max_k = {max_k} is below neighbours = {_show(opts.neighbours)}: the chord fit's kernels "
            "run from neighbours to max_k; raise max_k or lower neighbours"
        )
    return opts


def _with_suggestion(name: str, names: list[str]) -> str:
    """``name``, followed by the option it is closest to when there is one (``neighbors`` -> ``neighbours``)."""
    close = difflib.get_close_matches(name, names, n=1)
    return f"{name} (did you mean {close[0]}?)" if close else name


def check_options_for_cloud(options: Options, n_distinct: int, extent: float | None = None) -> None:
    """Refuse options that the cloud cannot carry: its number of distinct points, its size.

    :func:`resolve_options` checks each value against its own range; this
    checks the ones whose limit is the cloud's (see :class:`Options`, Notes):

    * ``neighbours``, ``min_neighbours`` and a fixed ``scale`` at most
      ``n_distinct - 2``: every ball leaves at least one point out (a ball of
      every point is no neighbourhood; ``neighbours = n - 2`` failed in the
      kernel choice);
    * ``k_local`` (``spacing="local"``) below ``n_distinct``;
    * ``radius`` at most half of ``extent``, the bounding box's diagonal (a
      larger ball around the cloud's centre holds the whole cloud; a unit
      sphere of 2000 points gave the wrong sign of the mean curvature at
      radius 2.5 = 0.72 of the diagonal, 1.6 % off at 2.0), and at least
      ``1e-9`` of it (smaller balls hold no neighbour: at 1e-100 the heat
      kernel's time underflowed and the mean-curvature normal was NaN).

    Parameters
    ----------
    options : Options
        Resolved options (:func:`resolve_options`).
    n_distinct : int
        Number of distinct points of the cloud.
    extent : float, optional
        Diagonal of the distinct points' bounding box; None skips the radius checks.

    Raises
    ------
    HeatcurvError
        One line naming the option, its value, the limit and the cloud's count or size.
    """
    n = int(n_distinct)
    most = n - 2
    counts = [("min_neighbours", options.min_neighbours)]
    if options.radius is None and (options.spacing == "density" or options.fit == "chord"):
        counts.insert(0, ("neighbours", options.neighbours))
    if options.fit == "chord" and options.radius is None and options.scale not in (None, "auto"):
        counts.append(("scale", options.scale))
    for name, value in counts:
        if value > most:
            raise HeatcurvError(
                f"{name} = {_show(value)} is too many for a cloud of {n} distinct points: at most {most} "
                "(every ball must leave a point out); lower it or give more points"
            )
    if options.radius is None and options.spacing == "local" and options.k_local >= n:
        raise HeatcurvError(
            f"k_local = {_show(options.k_local)} is too many for a cloud of {n} distinct points: at most {n - 1}"
        )
    if options.radius is not None and extent is not None and math.isfinite(extent) and extent > 0:
        radius = float(options.radius)
        if radius > extent / 2:
            raise HeatcurvError(
                f"radius = {_show(radius)} is larger than the cloud: at most half its bounding-box diagonal "
                f"({_show(extent / 2)}), where a ball around its centre holds all of it"
            )
        if radius < 1e-9 * extent:
            raise HeatcurvError(
                f"radius = {_show(radius)} is too small for a cloud of diagonal {_show(extent)}: at least 1e-9 "
                f"of it ({_show(1e-9 * extent)}); the balls would hold no neighbour"
            )
