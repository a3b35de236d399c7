"""The benchmark runs and cases `crackle validate` runs: each declared once, a case with the paper's
value, the band crackle's value must fall in and where that band comes from.

A run is one simulation (an example's quick or full form with overrides), named; docs/validation.md
names runs in its markers for the numbers it shows (`<!--q:RUN:NUMBER:FORMAT-->`). A case is one
number read from one run (several cases may read the same run: they share it). Its band is stated
with its source: the paper's own scatter (several samples, several meshes), a closed form's
tolerance, or crackle's measured scatter over draws when the paper gives one sample. A case crackle
does not reproduce says why in `reason` (then its band, if any, is what crackle gives today, so that
a change is still seen).

A NUMBER of a run: a summary.json key, dotted into dicts and lists (`peak_forces.top`,
`largest_fragment_velocity.2`), or one of EVENT_NUMBERS (read from events.csv), optionally times or
over a constant (`peak_stress*1e-6` for MPa, `brazilian_strength/3e6` for a ratio to ft).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..sweep.calibrate import summary_value

TIERS = ("quick", "full", "paper")
PAPERS = {
    "000": "paper 000: meshfree EFG thin shells, tubes under detonation (Li, Rabczuk et al.)",
    "001": "paper 001: FDEM with interface elements (the combined finite-discrete element method)",
    "002": "paper 002: Kirchhoff-Love shell, J-integral crack growth",
    "003": "paper 003: bonded-particle DEM (JCFpm) of a rock sample",
    "004": "paper 004: nut cracking (walnut shell, FDEM)",
    "closed-form": "closed-form checks",
}


def _failure_times(folder: Path):
    from ..io import read_events_csv

    path = folder / "events.csv"
    return read_events_csv(path)["time"] if path.exists() else []


# Numbers of a run that its summary does not hold: the first and last failure's time (s).
EVENT_NUMBERS = {
    "first_failure_time": lambda folder: min(_failure_times(folder), default=None),
    "last_failure_time": lambda folder: max(_failure_times(folder), default=None),
}
NUMBER = re.compile(r"^(?P<key>[\w.]+)(?:(?P<op>[*/])(?P<factor>[0-9.eE+-]+))?$")


def read_number(expression: str, summary: dict, folder: Path) -> float | None:
    """A run's number (the module's docstring says the expression's form), or None when the run has
    none (a missing key, NaN, no failure)."""
    parsed = NUMBER.match(expression)
    if parsed is None:
        raise ValueError(f"{expression!r} is not KEY, KEY*FACTOR or KEY/FACTOR")
    key = parsed["key"]
    raw = EVENT_NUMBERS[key](Path(folder)) if key in EVENT_NUMBERS else summary_value(summary, key)
    if raw is None or not math.isfinite(raw):
        return None
    factor = float(parsed["factor"]) if parsed["factor"] else 1.0
    return float(raw) / factor if parsed["op"] == "/" else float(raw) * factor


@dataclass(frozen=True)
class Run:
    """One simulation: a shipped example or a scenario file, its quick or full form, overrides
    (the same as `crackle run SCENARIO [--quick] --set KEY=VALUE ...`)."""

    name: str
    paper: str  # a key of PAPERS: whose numbers it gives
    scenario: str
    quick: bool = True
    overrides: dict = field(default_factory=dict)

    def settings(self) -> dict:
        return {"scenario": self.scenario, "quick": self.quick,
                "overrides": {k: repr(v) for k, v in self.overrides.items()}}

    def folder(self) -> str:
        """Its folder's name under a validation's output folder: the scenario, the form and a hash
        of the settings (a changed override is a new folder, never a stale result)."""
        digest = hashlib.sha1(json.dumps(self.settings(), sort_keys=True).encode()).hexdigest()[:8]
        return f"{Path(self.scenario).stem}-{'quick' if self.quick else 'full'}-{digest}"

    def command(self) -> str:
        sets = "".join(f" --set {k}={v}" for k, v in self.overrides.items())
        return f"crackle run {self.scenario}{' --quick' if self.quick else ''}{sets}"


def _runs(*runs: Run) -> dict[str, Run]:
    return {r.name: r for r in runs}


_MULTIPOINT_PLATES = {"2": ([90, 90], [0, 180]), "3": ([90] * 3, [0, 120, 240]),
                      "tetrahedron": ([0, 109.47, 109.47, 109.47], [0, 0, 120, 240]),
                      "5": ([90] * 5, [0, 72, 144, 216, 288]), "6": ([90] * 6, [0, 60, 120, 180, 240, 300])}
RUNS: dict[str, Run] = _runs(
    Run("direct-tension", "closed-form", "direct-tension"),
    Run("plate-impact", "000", "plate-impact"),
    Run("single-fracture", "001", "single-fracture"),
    Run("3pb", "001", "three-point-bending"),
    Run("sphere-slow", "001", "sphere-impact-slow"),
    Run("sphere-fast", "001", "sphere-impact-fast"),
    *(Run(f"brazilian-{a}", "001", "brazilian-disc", overrides={"loading.angle": a} if a else {})
      for a in (0, 30, 60, 90)),
    Run("brazilian-0-half-speed", "001", "brazilian-disc",
        overrides={"tools.0.speed": 0.025, "tools.1.speed": 0.025, "run.end_time": 3e-3}),
    Run("shell-centre-crack", "002", "shell-centre-crack"),
    Run("shell-centre-crack-full", "002", "shell-centre-crack", quick=False),
    Run("dem-ucs", "003", "dem-ucs"),
    Run("dem-brazilian", "003", "dem-brazilian"),
    Run("dem-tension", "003", "dem-tension"),
    Run("dem-triaxial", "003", "dem-triaxial"),
    *(Run(f"dem-damping-{a}", "003", "dem-ucs", overrides={"material.local_damping": a}) for a in (0.1, 0.4, 0.8)),
    *(Run(f"dem-damping-{a}-slow", "003", "dem-ucs",
          overrides={"material.local_damping": a, "tools.0.speed": 0.025, "run.end_time": 8e-3})
      for a in (0.1, 0.2, 0.4, 0.8)),
    *(Run(f"dem-flaw-{a}", "003", "dem-flaw", overrides={"flaw.angle": a}) for a in (0, 30, 60, 90)),
    *(Run(f"dem-closed-{a}", "003", "dem-flaw", overrides={"flaw.kind": "closed", "flaw.angle": a})
      for a in (0, 30, 60, 90)),
    Run("dem-ucs-full", "003", "dem-ucs", quick=False),
    Run("dem-brazilian-full", "003", "dem-brazilian", quick=False),
    Run("dem-tension-full", "003", "dem-tension", quick=False),
    Run("dem-flaw-90-full", "003", "dem-flaw", quick=False, overrides={"flaw.angle": 90}),
    Run("walnut-crush", "004", "walnut-crush"),
    *(Run(f"multipoint-{n}", "004", "walnut-multipoint",
          overrides={"plates.polar": polar, "plates.azimuth": azimuth})
      for n, (polar, azimuth) in _MULTIPOINT_PLATES.items()),
    Run("multipoint-4", "004", "walnut-multipoint"),
)


@dataclass(frozen=True)
class Case:
    """One benchmark number: `read` (a NUMBER of the run, in `unit`) compared with its band."""

    name: str
    paper: str  # a key of PAPERS
    tier: str  # quick, full or paper (the paper's own mesh or sample)
    run: Run
    quantity: str  # what is compared, in words
    read: str
    unit: str
    band: tuple[float, float]  # crackle's value passes inside [low, high] (in unit)
    band_source: str  # where the band comes from
    paper_value: str  # the paper's number, as the paper gives it (a value, a range)
    reason: str | None = None  # set when crackle does not reproduce the paper: why
    curve: str | None = None  # the report's figure: a curve of validation.figures.CURVES, in `unit`
    paper_number: float | None = None  # the paper's value in `unit`, drawn on that figure

    def value(self, summary: dict, folder: Path) -> float | None:
        return read_number(self.read, summary, folder)


CASES: tuple[Case, ...] = (
    # -- closed forms a run must give whatever the paper -------------------------------------------
    Case("closed-form-direct-tension", "closed-form", "quick", RUNS["direct-tension"],
         "nominal tensile strength of the pulled bar over ft", "tensile_strength_ratio", "", (0.95, 1.10),
         "closed form: the bar's material length E Gf / ft^2 = 144 mm exceeds its 10 mm section, so the section yields "
         "at once and the nominal strength is ft; up to +10 % for an unstructured mesh's faces oblique to the pull "
         "(1.026-1.041 measured over three element sizes, docs/validation.md 'Strength objectivity')", "1"),
    Case("closed-form-loading-index", "closed-form", "quick", RUNS["walnut-crush"],
         "loading index of two opposite plates", "loading_index", "", (1.1547005383, 1.1547005385),
         "closed form 2 / sqrt(3) = 1.15470053838 (paper 004's index for two opposite points), to 1e-10",
         "2 / sqrt(3)"),
    # -- paper 000: meshfree thin walls --------------------------------------------------------------
    Case("000-plate-impact-petals-quick", "000", "quick", RUNS["plate-impact"],
         "petals of the 10 mm Al plate perforated by the sphere at 300 m/s", "petals", "", (0.0, 0.0),
         "crackle's own count at every resolution it ran (quick, 15 mm, graded 3.5 mm): 0, a plug", "4 petals",
         reason="crackle perforates the plate by a plug at every resolution it ran, the sphere free or deformable "
                "(docs/validation.md, paper 000 section 4.2); petalling is issue 70"),
    # -- paper 001: FDEM ------------------------------------------------------------------------------
    Case("001-sphere-fast-energy", "001", "quick", RUNS["sphere-fast"], "energy error of the 100 m/s sphere impact",
         "energy_error*100", "%", (-3.0, 3.0), "the acceptance for violent runs: |energy error| < 3 %", "(not reported)"),
    Case("001-3pb-peak-quick", "001", "quick", RUNS["3pb"], "peak load on the top platen, h = 25 mm",
         "peak_forces.top", "N", (624.0, 762.0),
         "crackle's own value, 693 N, +-10 %: the paper gives no number, only that its coarse meshes over-estimate "
         "the converged peak by < 8 %", "coarse meshes within +8 % of the converged peak",
         reason="crackle's coarse mesh under-estimates its own converged peak (832.8 N at h = 5 mm) by 17 %, where "
                "the paper's coarse meshes over-estimate theirs by < 8 % (docs/validation.md, paper 001, "
                "three-point bending)", curve="load"),
    Case("001-brazilian-0-quick", "001", "quick", RUNS["brazilian-0"], "Brazilian disc's peak load, theta = 0",
         "peak_force", "N", (3044.0, 3720.0),
         "crackle's own quick value, 3382 N, +-10 % (the quick disc's peaks over loading angles and half the platen "
         "speed: 3227-3382 N)", "2130-2266 N (mean 2220, CV 2.4 %)",
         reason="the paper's mean is 0.79 ft by the elastic Brazilian relation, below the tensile strength it gave "
                "its rock: faces that open at ft split the disc at ~ft (crackle at the paper's 1.2 mm mesh: 1.05 ft, "
                "2968 N over four angles, CV 4.0 %); the quick 4 mm tets add about 15 % (docs/validation.md, paper "
                "001 section 4)", curve="load", paper_number=2220.0),
    # -- paper 002: Kirchhoff-Love shell ------------------------------------------------------------
    Case("002-centre-crack-j-quick", "002", "quick", RUNS["shell-centre-crack"],
         "J of the centre crack (2a/2b = 0.5, 100 MPa) over K^2 / E", "j_ratio", "", (0.80, 0.90),
         "closed form K^2 / E = 5,526 J/m^2 (Tada's K = 1.186 sigma sqrt(pi a)); constant-strain triangles reach it "
         "at first order in the cell size (0.849 at the quick 5 mm cells, 0.937 at 2.5 mm, 1.0004 extrapolated): "
         "the quick value +-5 %", "K^2 / E"),
    Case("002-centre-crack-j-full", "002", "full", RUNS["shell-centre-crack-full"],
         "J of the centre crack at 2.5 mm cells over K^2 / E", "j_ratio", "", (0.90, 0.97),
         "closed form K^2 / E as above; 0.937 at 2.5 mm cells, first order in the cell size: +-3 %", "K^2 / E"),
    # -- paper 003: DEM -------------------------------------------------------------------------------
    Case("003-ucs-quick", "003", "quick", RUNS["dem-ucs"], "uniaxial compressive strength", "peak_stress*1e-6", "MPa",
         (59.0, 75.0),
         "crackle's quick sample over twelve round-off draws: 59.4-73.8 MPa (docs/validation.md, paper 003); the "
         "paper's two samples (~70 MPa, 5 % apart) lie inside", "~70 MPa", curve="stress_strain", paper_number=70.0),
    Case("003-modulus-quick", "003", "quick", RUNS["dem-ucs"], "Young's modulus from the platen (20-50 % of the peak)",
         "platen_modulus*1e-9", "GPa", (49.5, 60.5),
         "the paper's ~55 GPa read from its stress-strain curve, +-10 % (it gives no scatter); crackle's draws "
         "scatter by 0.5 %", "~55 GPa"),
    Case("003-brazilian-quick", "003", "quick", RUNS["dem-brazilian"], "Brazilian tensile strength 2F / (pi D t)",
         "brazilian_strength*1e-6", "MPa", (3.76, 4.60),
         "crackle's own value, 4.18 MPa, +-10 % (the UCS's round-off scatter on the same packings)", "~6 MPa",
         reason="the full form reads 4.37 MPa (-27 %) and the quick 4.18: the bonds' strengths are the paper's, the "
                "packing's density and contacts are not (docs/validation.md, 'Full forms at the paper's density')"),
    Case("003-open-flaw-90-quick", "003", "quick", RUNS["dem-flaw-90"], "strength with an open flaw at theta = 90 deg",
         "peak_stress*1e-6", "MPa", (58.4, 71.4), "crackle's own quick value, 64.9 MPa (2026-12-06), +-10 % (round-off "
         "scatter)", "56 MPa",
         reason="the quick sample reads 16 % above the paper, as its intact strength rises with the particle size "
                "(docs/validation.md, paper 003, the UCS rows); the full form reads 57.3 MPa, +2 % (003-open-flaw-90-full)", curve="stress_strain", paper_number=56.0),
    Case("003-open-flaw-90-full", "003", "full", RUNS["dem-flaw-90-full"], "strength with an open flaw at theta = 90 deg "
         "(20,538 particles)", "peak_stress*1e-6", "MPa", (47.6, 64.4),
         "the paper's 56 MPa (Fig. 9-10), +-15 %: crackle's round-off scatter (~5 % a draw) and the paper's two "
         "intact samples 5 % apart; crackle's full form read 57.3 MPa (2026-11-27)", "56 MPa", curve="stress_strain", paper_number=56.0),
    Case("003-open-flaw-0-quick", "003", "quick", RUNS["dem-flaw-0"], "strength with an open flaw at theta = 0",
         "peak_stress*1e-6", "MPa", (36.4, 44.5), "crackle's own quick value, 40.5 MPa (2026-12-06), +-10 % (round-off "
         "scatter)",
         "29 MPa",
         reason="the 0-deg flaw weakens crackle's sample less than the paper's (0.58 of the intact strength against "
                "0.41; full form 35.0 MPa, 2026-11-27): neither the particle size nor the slot's width closes it "
                "(docs/validation.md, paper 003)", curve="stress_strain", paper_number=29.0),
    Case("003-tension-quick", "003", "quick", RUNS["dem-tension"], "direct tensile strength (peak reaction over the "
         "section)", "nominal_strength*1e-6", "MPa", (4.5, 5.55),
         "crackle's own quick value, 5.02 MPa, +-10 % (another seed: 4.94; grips twice as deep: 5.08)", "~6 MPa",
         reason="-16 %, as the full form's -19 %: the bonds fail at their own strength t = 4.5 MPa (ratio 1.115), "
                "below the paper's UTS (docs/validation.md, paper 003)"),
    Case("003-ucs-full", "003", "full", RUNS["dem-ucs-full"], "uniaxial compressive strength (20,703 particles)",
         "peak_stress*1e-6", "MPa", (55.0, 66.0),
         "crackle's three full-form runs, 58.0 / 62.0 / 61.0 MPa, and their round-off scatter (+-5 %)", "~70 MPa",
         reason="the full form reads 60.3 MPa on average, -14 %, at the paper's particle size and density "
                "(docs/validation.md, 'Full forms at the paper's density')", curve="stress_strain", paper_number=70.0),
    Case("003-modulus-full", "003", "full", RUNS["dem-ucs-full"], "Young's modulus from the platen (20,703 particles)",
         "platen_modulus*1e-9", "GPa", (49.5, 60.5),
         "the paper's ~55 GPa read from its stress-strain curve, +-10 %; crackle's full runs 55.6 and 55.7 GPa",
         "~55 GPa"),
    Case("003-brazilian-full", "003", "full", RUNS["dem-brazilian-full"], "Brazilian tensile strength (16,035 particles)",
         "brazilian_strength*1e-6", "MPa", (3.9, 4.8), "crackle's full-form 4.37 MPa, +-10 % (round-off scatter)",
         "~6 MPa",
         reason="-27 % at the paper's particle size and density, with the UCS's -14 % (docs/validation.md)"),
    Case("003-tension-full", "003", "full", RUNS["dem-tension-full"], "direct tensile strength (20,703 particles)",
         "nominal_strength*1e-6", "MPa", (4.35, 5.3), "crackle's full-form 4.84 MPa, +-10 % (round-off scatter)",
         "~6 MPa",
         reason="-19 %: the bonds fail at their own strength t = 4.5 MPa (ratio 1.075), below the paper's UTS "
                "(docs/validation.md, paper 003)"),
    # -- paper 004: nuts ------------------------------------------------------------------------------
    Case("004-walnut-crush-quick", "004", "quick", RUNS["walnut-crush"], "uniaxial crush peak force", "peak_force", "N",
         (217.6, 266.0),
         "crackle's own quick value, 241.8 N, +-10 % (the quick mesh's peaks over code changes 241.8-244.6 N; "
         "219-228 N between 40 and 200 mm/s)", "~237 N (converged, 0.95 mm)",
         reason="the quick 3 mm mesh at 1.25 m/s reads 242 N, but the agreement does not carry to the converged "
                "mesh: at 1.0 and 0.95 mm and the paper's 40 mm/s crackle reads 182-186 N, 0.77 of the paper's "
                "(docs/validation.md, paper 004)", curve="load", paper_number=236.6),
)


# The cases whose runs take seconds: what the test suite reruns to check docs/validation.md's
# validate block against the code (tests/core/test_validate.py).
FAST_CASES = ("closed-form-direct-tension", "002-centre-crack-j-quick", "000-plate-impact-petals-quick")


def select(papers: list[str] | None, tier: str, names: list[str] | None = None) -> list[Case]:
    """The cases of these papers (all when none) at this tier, or those named (ValueError for a
    name or paper that is not one)."""
    if tier not in TIERS:
        raise ValueError(f"--tier {tier}: choose one of {', '.join(TIERS)}")
    unknown = [p for p in papers or () if p not in PAPERS]
    if unknown:
        raise ValueError(f"unknown paper {unknown[0]!r}: choose among {', '.join(PAPERS)}")
    known = {case.name: case for case in CASES}
    missing = [n for n in names or () if n not in known]
    if missing:
        raise ValueError(f"unknown case {missing[0]!r}; the cases: {', '.join(known)}")
    chosen = [known[n] for n in names] if names else \
        [c for c in CASES if c.tier == tier and (not papers or c.paper in papers)]
    if not chosen:
        raise ValueError(f"no case of {', '.join(papers or ['any paper'])} at tier {tier}")
    return chosen
