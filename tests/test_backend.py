"""heatcurv.backend: numba threads (numba is required; one implementation per hot stage)."""

from heatcurv.backend import threads


def test_threads_sets_numba_threads_for_this_thread_only():
    """numba's thread count is thread-local: threads(1) limits this thread's kernels, not another thread's."""
    import threading

    import numba

    default = numba.get_num_threads()
    seen = {}
    with threads(1):
        assert numba.get_num_threads() == 1
        other = threading.Thread(target=lambda: seen.setdefault("other", numba.get_num_threads()))
        other.start()
        other.join()
    assert numba.get_num_threads() == default and seen["other"] == default
    with threads(None), threads(-1):
        assert numba.get_num_threads() == default
