"""The infrastructure under the stages: files, locks, background work and parallel execution.

- :mod:`.files`: the inputs a command reads and the outputs it writes (:class:`~.files.Outputs`:
  paths checked before any computing, atomic commits, locks, clean-up on a signal);
- :mod:`.background`: one piece of output work (the figures) in a child process beside the pipeline;
- :mod:`.executor`: the one executor interface for parallel work (local processes and threads, or
  Dask distributed when a scheduler is given);
- :mod:`.blas`: one BLAS thread for the many small dense problems of the margins and checks.

Nothing here knows about control: the stages (:mod:`commission.tune`, :mod:`commission.validate`, ...)
import it, never the other way round.
"""
