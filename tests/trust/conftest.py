"""Counts of the generated cases per class and outcome, printed at the end of the session."""

from __future__ import annotations

from collections import Counter

COUNTS: Counter = Counter()


def pytest_terminal_summary(terminalreporter):
    if not COUNTS:
        return
    terminalreporter.write_sep("-", "tests/trust: generated cases (class, outcome)")
    for cls in sorted({c for c, _ in COUNTS}):
        row = {o: n for (c, o), n in COUNTS.items() if c == cls}
        terminalreporter.write_line(
            f"{cls:10s} total {sum(row.values()):5d}  " + "  ".join(f"{o} {n}" for o, n in sorted(row.items()))
        )
    terminalreporter.write_line(f"{'all':10s} total {sum(COUNTS.values()):5d}")
