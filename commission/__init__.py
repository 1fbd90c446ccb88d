"""commission: commission precision linear-motor axes.

Pipeline layer (data model, I/O, orchestration).  The pure numerics live in
:mod:`commission.identify` and :mod:`commission.controllers`; the command line
in :mod:`commission.cli`.  Dependencies point one way: cli -> commission ->
identify, controllers.
"""

__version__ = "0.1.0"
