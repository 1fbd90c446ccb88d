"""Command registry: name -> (module, one-line help), in pipeline order.

``commission --help`` lists these lines without importing any module (the
numerics load only when a command runs: :class:`commission.cli.main.LazyGroup`).
Each module registers its command on :data:`commission.cli.main.app` when imported.
"""

COMMANDS: dict[str, tuple[str, str]] = {
    "excite": ("commission.cli.excite_cmd",
               "Plan an excitation run within the machine's limits (friction ladder, moves, broadband "
               "injection); pre-simulate it; write plan.csv/.h5/.json/.png."),
    "identify": ("commission.cli.identify_cmd",
                 "Identify M, B, friction and offset from a position-only excitation log; write ident.json."),
    "tune": ("commission.cli.tune_cmd",
             "Tune the discrete output-feedback ARC (and the PID baseline) for an identified axis."),
    "validate": ("commission.cli.validate_cmd",
                 "Simulate ARC and PID on every scenario; write controller.json only if every gate passes "
                 "(else exit 1)."),
    "run": ("commission.cli.run_cmd",
            "Identify the axis, tune the ARC, validate it; exit 0 with controller.json when every gate "
            "passes, else 1."),
    "fleet": ("commission.cli.fleet_cmd",
              "Commission every axis of a manifest (one run each) and summarise the fleet; exit 0 only if all "
              "passed."),
    "export": ("commission.cli.export_cmd",
               "Write the validated controller.json's step as C99 (header, source, test vectors, replay program)."),
    "paper-table": ("commission.cli.paper_cmd",
                    "Simulate Sets 1-3 and Case 2 with the paper's PID and ARC; print Table 1."),
}
