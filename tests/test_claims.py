"""What README.md and docs/*.md state about the code's own vocabulary, read from the code: a
list in the docs that the code has outgrown fails here, naming what is missing.

* summary.json's statuses: "running" (written as a run starts, cosserat_fem/analysis/simulation.py)
  and every status cosserat_fem.io.run_folder.status_of gives a run's end, one for each kind of
  ending (none, Ctrl-C, a StopError, any other error).
"""

from __future__ import annotations

import re

from conftest import ROOT

from cosserat_fem.common.errors import SolverError, StopError
from cosserat_fem.io.run_folder import status_of

README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_the_readme_names_every_status_of_summary_json():
    found = re.search(r"`summary\.json`: status \((.*?)\)", README, re.S)
    assert found, "README.md no longer lists summary.json's statuses"
    named = set(re.findall(r'"([a-z]+)"', found.group(1)))
    endings = (
        None,
        KeyboardInterrupt(),
        StopError("a limit"),
        SolverError("trouble"),
        RuntimeError("a bug"),
    )
    assert named == {"running"} | {status_of(failure) for failure in endings}
