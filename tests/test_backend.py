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


def test_small_blocks_run_side_by_side_on_the_row_pool_and_large_ones_in_turn():
    """map_blocks: one pool owns the worker threads. Blocks too small for a kernel to split share the row pool's
    threads (no other pool is started); blocks of SPLIT_ROWS rows or more run one after the other on this thread,
    whose kernels split them. Results come back in order either way."""
    import threading

    import numba

    from heatcurv._kernels import MIN_ROWS_PER_CHUNK, SPLIT_ROWS
    from heatcurv.backend import map_blocks

    assert SPLIT_ROWS == 2 * MIN_ROWS_PER_CHUNK  # a call splits from two chunks on

    def record(block):
        return block * block, threading.current_thread().name

    blocks = list(range(40))
    with threads(2):
        small = list(map_blocks(record, blocks, SPLIT_ROWS - 1))
        large = list(map_blocks(record, blocks, SPLIT_ROWS))
    assert [r for r, _ in small] == [b * b for b in blocks] == [r for r, _ in large]
    here = threading.current_thread().name
    assert {name for _, name in large} == {here}
    assert {name for _, name in small} <= {here, "heatcurv-kernels"}
    if numba.config.NUMBA_NUM_THREADS > 1:
        # side by side for real: the first two blocks meet at a barrier, which one thread alone never passes
        barrier = threading.Barrier(2, timeout=20)

        def meet(block):
            if block < 2:
                barrier.wait()
            return threading.current_thread().name

        with threads(2):
            assert set(map_blocks(meet, blocks, 1)) == {here, "heatcurv-kernels"}
    with threads(1):
        assert {name for _, name in map_blocks(record, blocks, 1)} == {here}


def test_an_error_in_a_block_run_side_by_side_is_raised_once_the_others_stop():
    import pytest

    from heatcurv.backend import map_blocks

    def fail_on_seven(block):
        if block == 7:
            raise ValueError("block 7")
        return block

    with threads(2), pytest.raises(ValueError, match="block 7"):
        list(map_blocks(fail_on_seven, list(range(20)), 10))
