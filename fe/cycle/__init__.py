"""The load-cycle driver every kind of hinge runs its hysteresis cycle through.

:mod:`fe.cycle.driver` owns the loop that all kinds share: the stages of
``CycleSettings.stages()`` (0 → +Fg → −Fg → +Fg …), each stage's force targets, the
increments recorded on the way, the partial result kept when an increment fails, the
progress calls and the timing. A kind supplies its step (``CycleStep``): the targets of a
stage, how one target is reached from the last, and the result of its increments — as
dolfinx keeps ``NewtonSolver`` apart from the ``NonlinearProblem`` it solves.
"""
