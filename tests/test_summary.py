"""The --json summary line is strict JSON: non-finite figures become null."""
import json
import math

import numpy as np

from trumans.summary import json_safe, print_summary


def test_non_finite_figures_are_null_and_numpy_is_plain(capsys):
    summary = {"a": float("nan"), "b": [1.0, float("inf"), np.float32(2.5)], "c": {"d": np.float64(-np.inf)},
               "e": np.arange(3), "f": "text", "g": 3}
    print_summary(summary)
    line = capsys.readouterr().out.strip().splitlines()[-1]
    back = json.loads(line, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
    assert back == {"a": None, "b": [1.0, None, 2.5], "c": {"d": None}, "e": [0, 1, 2], "f": "text", "g": 3}


def test_json_safe_keeps_finite_values_exactly():
    x = {"pi": math.pi, "n": [0.1, -2.0]}
    assert json_safe(x) == x


def test_every_command_prints_its_json_line_through_print_summary():
    """A command printing ``json.dumps(...)`` itself could print NaN (not JSON) for a figure nothing
    measured; every --json line goes through ``print_summary`` (sample, eval synthesis / safety,
    scene inspect and the local-query benchmark did not)."""
    import re
    from pathlib import Path

    import trumans

    pkg = Path(trumans.__file__).parent
    offenders = [f"{p.relative_to(pkg)}:{i}" for p in sorted(pkg.rglob("*.py"))
                 for i, line in enumerate(p.read_text().splitlines(), 1)
                 if re.search(r"print\(\s*json\.dumps\(", line) and p.name != "summary.py"]
    assert offenders == []
