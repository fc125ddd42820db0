"""The residual case matrix's report: what ``make evaluate`` prints (one line per case, the confusion table, a
line per family, last :func:`summary_line`)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

from torque_estimator.evaluation.residual_cases.case import Case, CaseResult
from torque_estimator.evaluation.residual_cases.catalogue import families, small_matrix
from torque_estimator.evaluation.residual_cases.runner import run_matrix


def confusion(results: Sequence[CaseResult]) -> dict[str, dict[str, int]]:
    """true effect -> {column: count of cases}: the column of the effect itself when it was found, "missed"
    when not, and every false name found with it; a case without vocabulary effects has the row "none" (or
    its out-of-vocabulary effect) and the column "none" when nothing was named."""
    table: dict[str, dict[str, int]] = {}

    def count(row: str, column: str) -> None:
        table.setdefault(row, {})[column] = table.get(row, {}).get(column, 0) + 1

    for r in results:
        if r.truth:
            for t in r.truth:
                count(t, t if t in r.found else "missed")
                for f in r.false_names:
                    count(t, f)
        else:
            for f in r.false_names or ("none",):
                count("+".join(r.case.extra) or "none", f)
    return table


def summary_line(results: Sequence[CaseResult]) -> str:
    """``residuals: cases= exact= false_names= missed= at_floor= unexplained_oov= unphysical= passed=``."""
    oov = [r for r in results if r.case.extra]
    in_vocab = [r for r in results if not r.case.extra]
    return (f"residuals: cases={len(results)} exact={sum(r.exact for r in results)} "
            f"false_names={sum(len(r.false_names) for r in results)} missed={sum(len(r.missed) for r in results)} "
            f"at_floor={sum(r.within_floor for r in in_vocab)}/{len(in_vocab)} "
            f"unexplained_oov={sum(r.unexplained is not None for r in oov)}/{len(oov)} "
            f"unphysical={sum(bool(r.unphysical) for r in results)} "
            f"passed={sum(r.passed for r in results)}")


def format_results(results: Sequence[CaseResult]) -> list[str]:
    """One line per case (with the mu correction: identified / the simulated rig's), then the confusion table."""
    lines = ["  case                                                    found                          before   "
             "after    floor   after/floor  unexplained  mu/true"]
    for r in results:
        found = ",".join(r.found) or "none"
        unexpl = f"{r.unexplained:.4f}" if r.unexplained is not None else "-"
        mark = "" if r.passed else "  <- FAIL" + (f" (negative {', '.join(r.unphysical)})" if r.unphysical else "")
        lines.append(f"  {r.case.name:<55} {found:<30} {r.rms_before:.4f}  {r.rms_after:.4f}  {r.floor:.4f}  "
                     f"{r.rms_after / r.floor:5.2f}        {unexpl:<11}  {r.mu_ratio:5.3f}{mark}")
    lines += confusion_lines(results)
    return lines


def confusion_lines(results: Sequence[CaseResult], title: str = "") -> list[str]:
    """The confusion table (true rows, found columns) of ``results``."""
    table = confusion(results)
    columns = sorted({c for row in table.values() for c in row}, key=lambda c: (c in ("missed", "none"), c))
    width = max(len(t) for t in table) + 2
    lines = [f"  confusion{title} (rows: true effect, columns: effects found; counts of cases)",
             "  " + " " * width + " ".join(f"{c[:8]:>8}" for c in columns)]
    for t in sorted(table, key=lambda x: (x == "none", x)):
        lines.append("  " + f"{t:<{width}}" + " ".join(f"{table[t].get(c, 0) or '.':>8}" for c in columns))
    return lines


def family_lines(results: Sequence[CaseResult]) -> list[str]:
    """One summary line per family of :func:`families` that ``results`` covers."""
    by_name = {r.case.name: r for r in results}
    lines = []
    for family, cases in families().items():
        mine = [by_name[c.name] for c in cases if c.name in by_name]
        if mine:
            lines.append(f"  {family:<13} " + summary_line(mine).removeprefix("residuals: "))
    return lines


def evaluate_lines(cases: Sequence[Case] | None = None, progress: Callable[[int], None] | None = None) -> list[str]:
    """What ``make evaluate`` prints: a heading, one line per case, the confusion table, a line per family,
    and last the :func:`summary_line` (default: :func:`small_matrix`)."""
    cases = small_matrix() if cases is None else list(cases)
    start = time.monotonic()
    results = run_matrix(cases, progress=(lambda k, _r: progress(k)) if progress else None)
    return ([f"\nresiduals on the simulated rigs: {len(cases)} cases (true effects vs effects_found; rig files "
             f"{', '.join(sorted({c.rig for c in cases}))}; declared values off by mu +-30 %, K_t +-5 %, drags x2, "
             f"inertia +-20 %, oil reference +-15 K, or mu +25 % and K_t +3 % with sources, or drags declared 0), "
             f"{time.monotonic() - start:.0f} s"] + format_results(results) + ["  by family:"]
            + family_lines(results) + [summary_line(results)])
