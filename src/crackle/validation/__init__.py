"""`crackle validate`: the papers' benchmarks as declared cases (cases.py) with the paper's value
and a band, run and reported (runner.py)."""

from .cases import CASES, PAPERS, TIERS, Case, select
from .runner import CaseResult, exit_code, validate

__all__ = ["CASES", "PAPERS", "TIERS", "Case", "CaseResult", "exit_code", "select", "validate"]
