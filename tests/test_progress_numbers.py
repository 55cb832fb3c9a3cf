"""RunProgress: progress numbers over a run of several objectives only rise
(flightid.estimation.progress)."""

from flightid.estimation.progress import RunProgress, next_stage


def test_stages_continue_the_numbering():
    calls = []
    progress = RunProgress(lambda p, e, c: calls.append((p, e, c)))
    # stage 1: passes 0..2 after 0, 5, 9 evaluations; 12 spent in all (the last 3 unreported)
    for p, e in ((0, 0), (1, 5), (2, 9)):
        progress(p, e, 10.0 - p)
    next_stage(progress, 12)
    # stage 2 counts from zero again
    for p, e in ((0, 1), (1, 4)):
        progress(p, e, 5.0 - p)
    # a total below what was reported cannot move the count back
    next_stage(progress, 3)
    progress(0, 0, 1.0)
    assert calls == [
        (0, 0, 10.0),
        (1, 5, 9.0),
        (2, 9, 8.0),
        (3, 13, 5.0),
        (4, 16, 4.0),
        (5, 16, 1.0),
    ]


def test_wrap_and_next_stage_leave_none_and_plain_callables_alone():
    assert RunProgress.wrap(None) is None
    calls = []
    plain = calls.append
    next_stage(plain, 10)  # not a RunProgress: nothing happens
    next_stage(None, 10)
    assert calls == []
