"""Text of the validation report (``report.md``) and of the stdout summary.

No plotting here: the figures are drawn by the CLI (``cli/plots_validate.py``) and only linked
by name.  Every unit is the axis's (``result.units``: m or rad, :mod:`commission.units`).

Modules
-------
* :mod:`~commission.report.document`: the whole report (:func:`report_markdown`) and its sections in
  order: verdict, axis and controllers, robustness, gate, indexes, figures, provenance;
* :mod:`~commission.report.verdict`: the verdict in words for stdout and the report's first lines
  (:func:`summary_text`, :func:`summary_rows`, :func:`verdict_text`, :func:`refusal_lines`,
  :func:`not_better_lines`, :func:`validity_lines`);
* :mod:`~commission.report.tables`: the performance indexes in the layout of Table 1 of Xu & Yao (2001)
  (:func:`table1_markdown`), the Monte-Carlo summary (:func:`monte_carlo_summary`), the parameter
  estimates and the gate's table;
* :mod:`~commission.report.identification`: the identification section (:func:`identification_markdown`);
* :mod:`~commission.report.discussion`: "Reading the results" (:func:`theta_convergence`,
  :func:`excitation_level`, :func:`pid_limit_cycle`);
* :mod:`~commission.report.margins`: the stability margins and the whole theta box;
* :mod:`~commission.report.text`: numbers rounded for people and input text escaped for Markdown
  (:func:`md_code`, :func:`md_text`);
* :mod:`~commission.report.labels`: every word table (index headings from the one index table,
  :data:`commission.controllers.metrics.INDEX_TABLE`; case titles; criterion and parameter wording;
  figure captions).
"""

from commission.report.discussion import excitation_level, pid_limit_cycle, theta_convergence
from commission.report.document import report_markdown
from commission.report.identification import identification_markdown
from commission.report.tables import monte_carlo_summary, table1_markdown
from commission.report.text import md_code, md_text
from commission.report.verdict import (not_better_lines, refusal_lines, summary_rows, summary_text, validity_lines,
                                       verdict_text)

__all__ = [
    "report_markdown", "summary_text", "summary_rows", "verdict_text", "refusal_lines", "not_better_lines",
    "validity_lines", "table1_markdown", "monte_carlo_summary", "identification_markdown", "md_code", "md_text",
    "excitation_level", "pid_limit_cycle", "theta_convergence",
]
