"""The load-cycle driver every kind of hinge runs its hysteresis cycle through.

:mod:`fe.cycle.driver` owns the loop that all kinds share: the stages of
``CycleSettings.stages()`` (0 → +Fg → −Fg → +Fg …), each stage's force targets, the
increments recorded on the way, the partial result kept when an increment fails, the
progress calls and the timing. A kind supplies its step (``CycleStep``): the targets of a
stage, how one target is reached from the last, and the result of its increments — as
dolfinx keeps ``NewtonSolver`` apart from the ``NonlinearProblem`` it solves.

:mod:`fe.cycle.protocol` holds the load history as data (``CycleSettings``) and
:mod:`fe.cycle.result` the result of every kind (``CycleResult``: loop, η, energy
balance). Any kind's result is written by :mod:`fe.cycle.loop_files` (loop.csv, loop.png)
and, with the kind's displacement fields, by :mod:`fe.cycle.fields` (a ParaView series).
"""
