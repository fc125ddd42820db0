"""The residual case matrix's command line: ``python -m torque_estimator.evaluation.residual_cases`` runs the
matrix, a family of it (``--family NAME``) or the small subset and prints what ``make evaluate`` prints."""

from __future__ import annotations

import argparse

from torque_estimator.evaluation.residual_cases.catalogue import families, full_matrix, small_matrix
from torque_estimator.evaluation.residual_cases.report import evaluate_lines


def main(argv: list[str] | None = None) -> int:
    """Run the matrix, a family of it, or the small subset, and print what ``make evaluate`` prints."""
    names = list(families())
    p = argparse.ArgumentParser(prog="python -m torque_estimator.evaluation.residual_cases",
                                description="The residual tool's case matrix on the simulated rigs: each case "
                                            "simulates a data set, gives `residuals` a rig file with its numbers off, "
                                            "and scores the names it finds against the true ones.")
    p.add_argument("--cases", choices=("full", "small"), default="small",
                   help="the full matrix (every family) or the small subset (default)")
    p.add_argument("--family", choices=names, action="append", default=None,
                   help="run only this family of the full matrix (repeatable); overrides --cases")
    p.add_argument("--match", default=None, help="run only the cases whose name contains this text")
    args = p.parse_args(argv)
    if args.family:
        groups = families()
        cases = [c for f in args.family for c in groups[f]]
    else:
        cases = full_matrix() if args.cases == "full" else small_matrix()
    if args.match:
        cases = [c for c in cases if args.match in c.name]
    print("\n".join(evaluate_lines(cases, progress=lambda k: print(f"  [{k}/{len(cases)}]", end="\r",
                                                                   flush=True))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
