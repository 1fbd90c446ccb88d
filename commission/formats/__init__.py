"""Input and output file formats, one table each (issue #34).

:mod:`commission.formats.table` holds the machinery (a row per key, the strict
pydantic model built from the rows, the error line naming the key path, the
JSON Schema, the ``--help`` and Markdown renderings);
:mod:`commission.formats.spec_toml` is ``spec.toml``'s table,
:mod:`commission.formats.gate_toml` ``gate.toml``'s and :mod:`commission.formats.limits_toml` ``limits.toml``'s.  The JSON artifacts nest deeper:
:mod:`commission.formats.json_table` holds their machinery (a row per JSON path, nested strict
models, error lines naming ``$.theta.min[2]``), :mod:`commission.formats.ident_json` is
``ident.json``'s table, :mod:`commission.formats.tuning_json` ``tuning.json``'s and
:mod:`commission.formats.controller_json` ``controller.json``'s,
:mod:`commission.formats.validation_json` ``validation.json``'s and :mod:`commission.formats.plan_json`
``plan.json``'s (the excitation plan).  The JSON tables and limits.toml's are text tables, one row a line
(:func:`commission.formats.json_table.rows`, :func:`commission.formats.table.keys`), with helpers
for the rows that repeat (a score, a gate check, a controller's gains).  The generated
files (docs/schemas/*.schema.json and the key tables of docs/interface.md) are
rewritten by ``python -m commission.formats`` (:func:`commission.formats.generated.write_generated`) and
compared with the tables by the tests.  This package imports no simulation code.
"""
