"""heatcurv.cli.console: exit statuses and the stdout messages of --quiet / --verbose."""

import io as stdio

from heatcurv.cli.console import EXIT_BAD_INPUT, EXIT_BUG, EXIT_INTERRUPTED, EXIT_OK, Log


def test_exit_statuses():
    assert (EXIT_OK, EXIT_BUG, EXIT_BAD_INPUT, EXIT_INTERRUPTED) == (0, 1, 2, 130)


def test_log_levels():
    out = stdio.StringIO()
    for quiet, verbose, expected in [(False, False, "info\n"), (False, True, "info\ndetail\n"), (True, True, "")]:
        out.seek(0), out.truncate()
        log = Log(quiet=quiet, verbose=verbose, stream=out)
        log.info("info")
        log.detail("detail")
        assert out.getvalue() == expected
