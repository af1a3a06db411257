"""``heatcurv view INPUT``: an interactive view of a cloud and its fields, one self-contained HTML page."""

from __future__ import annotations

import os
import re
import sys
import webbrowser
from pathlib import Path

import numpy as np

from ..errors import HeatcurvError
from .console import EXIT_OK, Log
from .fields import COMPUTED_FIELDS, DEFAULT_FIELDS
from .picture import field_from_file, file_normals
from .steps import check_output_path, read_cloud

__all__ = ["run", "default_output", "file_fields", "open_in_browser"]


def default_output(input_path) -> Path:
    """The page next to the input: ``scan.ply`` -> ``scan.html``."""
    return Path(input_path).with_suffix(".html")


def file_fields(cloud) -> dict:
    """The file's scalar fields in its order: ``nx ny nz`` (its normals) first, then every other property.

    Colours are not fields here (a cloud's RGB is not a quantity to colour by);
    the coordinates are added by :func:`heatcurv.view.write_view`.
    """
    fields = {}
    if cloud.normals is not None:
        fields.update({name: cloud.normals[:, k] for k, name in enumerate(("nx", "ny", "nz"))})
    fields.update({name: np.asarray(values) for name, values in cloud.fields.items()})
    return fields


def _chosen_fields(fields: dict, wanted, field, path) -> dict:
    """``fields`` restricted to ``--fields`` (in that order), checking ``--field`` against what is there."""
    known = list(fields) + ["x", "y", "z"]
    if wanted is not None:
        unknown = [name for name in wanted if name not in known]
        if unknown:
            raise HeatcurvError(f"--fields: {path} has no field {', '.join(map(repr, unknown))}; "
                                f"it holds {', '.join(known)}")
        fields = {name: fields[name] for name in wanted if name in fields}
    if field is not None and field not in known:
        raise HeatcurvError(f"--field: {path} has no field {field!r}; it holds {', '.join(known)}")
    if field is not None and wanted is not None and field not in wanted:
        raise HeatcurvError(f"--field {field!r} is not among --fields {','.join(wanted)}")
    return fields


def _graphical() -> bool:
    """Whether a graphical browser can open here: Windows, macOS, or a Linux/BSD desktop session."""
    if sys.platform in ("win32", "darwin"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def open_in_browser(path: Path) -> bool:
    """Open the page in the desktop's web browser; False where there is none (no display, a text-only browser).

    A text browser (lynx, w3m) would take over the terminal and cannot draw
    WebGL: it is never started.
    """
    if not _graphical():
        return False
    try:
        browser = webbrowser.get()
    except webbrowser.Error:
        return False
    if type(browser) is webbrowser.GenericBrowser:  # a console browser, run in the foreground
        return False
    try:
        return bool(browser.open(path.resolve().as_uri()))
    except Exception:  # a browser that fails to start is no reason to fail: the page is written
        return False


def field_names(text: str) -> tuple:
    """argparse type of ``--fields``: comma- or space-separated names."""
    names = tuple(n for n in re.split(r"[,\s]+", text.strip()) if n)
    if not names:
        import argparse

        raise argparse.ArgumentTypeError("expected a comma-separated list of field names")
    return names


def run(args, log: Log) -> int:
    """Run ``heatcurv view`` on the parsed arguments."""
    from ..view import HTML_EXTENSIONS, write_view

    output = args.output if args.output is not None else default_output(args.input)
    output = check_output_path(output, HTML_EXTENSIONS, "page", args.input)
    cloud = read_cloud(args.input, log)
    fields = _chosen_fields(file_fields(cloud), args.fields, args.field, args.input)
    reliable = field_from_file(cloud, "reliable")
    note = None
    if not set(COMPUTED_FIELDS) & set(cloud.fields):
        note = (f"{Path(args.input).name} holds no curvature: 'heatcurv compute {Path(args.input).name} "
                "-o OUTPUT.ply' computes it.")
    view = write_view(
        cloud.points, fields, output, file_normals(cloud), field=args.field,
        reliable=None if reliable is None else np.asarray(reliable) != 0,
        grey_unreliable=[name for name in DEFAULT_FIELDS if name != "reliable"],
        max_points=args.max_points, percentiles=args.percentiles, length_unit=args.unit,
        vertical="z" if (cloud.format or "") in ("las", "laz") else "y",
        title=args.title if args.title is not None else Path(args.input).name, note=note,
    )
    shown = f"a random {view.shown} of {view.total}" if view.shown < view.total else f"{view.shown}"
    log.info(f"wrote {output}: {shown} points, {len(view.fields)} field(s), first {view.field}; "
             f"{view.size / 1e6:.1f} MB")
    if view.shown < np.isfinite(cloud.points).all(axis=1).sum():
        log.info(f"  the page shows a random {view.shown} points (--max-points N shows more, in a bigger page)")
    if note is not None:
        log.info(f"  {note}")
    if not args.no_browser and log.stream.isatty() and open_in_browser(Path(output)):
        log.info("  opened in the web browser")
    else:
        log.info(f"  open it in a web browser: {Path(output).resolve().as_uri()}")
    return EXIT_OK
