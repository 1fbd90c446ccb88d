"""Text that came from an input file reaches report.md escaped: no link, tag or markup of its own."""

from __future__ import annotations

import copy
import json
from pathlib import Path

from commission.report import identification_markdown, md_code, md_text
from commission.tuning import Tuning

TUNING_DOC = json.loads((Path(__file__).parent / "data" / "tuning_paper_budget8.json").read_text())
HOSTILE = "log.h5` <img src=x onerror=alert(1)> [click](javascript:alert(1))\n# heading | cell *bold*"


def test_free_text_is_escaped_for_a_paragraph_and_for_a_code_span():
    text = md_text(HOSTILE)
    assert "<" not in text and ">" not in text and "\n" not in text
    assert "](" not in text.replace("\\](", "")  # every link bracket escaped
    for ch in "*|#[]`":
        assert all(text[i - 1] == "\\" for i, c in enumerate(text) if c == ch), ch
    code = md_code(HOSTILE)
    assert code.startswith("`") and code.endswith("`") and code.count("`") == 2 and "\n" not in code


def test_the_identification_section_quotes_the_log_path_and_notes_escaped():
    doc = copy.deepcopy(TUNING_DOC)
    ident = doc["identification"]
    ident.setdefault("source", {})["path"] = HOSTILE
    ident["frequency_response"] = {"note": HOSTILE}
    section = "\n".join(identification_markdown(Tuning.from_dict(doc)))
    assert md_code(HOSTILE) in section and md_text(HOSTILE) in section
    outside_code = section.replace(md_code(HOSTILE), "")  # inside a code span nothing is interpreted
    assert "<img" not in outside_code and "[click](" not in outside_code and "\n# heading" not in outside_code
