"""The benchmark cases `crackle validate` runs: each declared once, with the paper's value, the band
crackle's value must fall in and where that band comes from.

A case is one number read from one run (several cases may read the same run: they share it). Its
band is stated with its source: the paper's own scatter (several samples, several meshes), a
closed form's tolerance, or crackle's measured scatter over draws when the paper gives one
sample. A case crackle does not reproduce says why in `reason` (then its band, if any, is what
crackle gives today, so that a change is still seen).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

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


@dataclass(frozen=True)
class Case:
    """One benchmark number. `read`: a summary.json key, dotted into dicts and lists, times `scale`
    (the value crackle reports, in `unit`)."""

    name: str
    paper: str  # a key of PAPERS
    tier: str  # quick, full or paper (the paper's own mesh or sample)
    scenario: str  # a shipped example or a scenario file
    quantity: str  # what is compared, in words
    read: str
    unit: str
    band: tuple[float, float]  # crackle's value passes inside [low, high] (in unit)
    band_source: str  # where the band comes from
    paper_value: str  # the paper's number, as the paper gives it (a value, a range)
    overrides: dict = field(default_factory=dict)
    scale: float = 1.0
    reason: str | None = None  # set when crackle does not reproduce the paper: why

    @property
    def quick(self) -> bool:
        return self.tier == "quick"

    def run_key(self) -> tuple:
        """Cases with the same key read the same run."""
        return (self.scenario, self.quick, tuple(sorted((k, repr(v)) for k, v in self.overrides.items())))

    def value(self, summary: dict) -> float | None:
        raw = summary_value(summary, self.read)
        return None if raw is None or not math.isfinite(raw) else raw * self.scale


CASES: tuple[Case, ...] = (
    # -- closed forms a run must give whatever the paper -------------------------------------------
    Case("closed-form-direct-tension", "closed-form", "quick", "direct-tension",
         "nominal tensile strength of the pulled bar over ft", "tensile_strength_ratio", "", (0.95, 1.10),
         "closed form: the bar's material length E Gf / ft^2 = 144 mm exceeds its 10 mm section, so the section yields "
         "at once and the nominal strength is ft; up to +10 % for an unstructured mesh's faces oblique to the pull "
         "(1.026-1.041 measured over three element sizes, docs/validation.md 'Strength objectivity')", "1"),
    Case("closed-form-loading-index", "closed-form", "quick", "walnut-crush",
         "loading index of two opposite plates", "loading_index", "", (1.1547005383, 1.1547005385),
         "closed form 2 / sqrt(3) = 1.15470053838 (paper 004's index for two opposite points), to 1e-10",
         "2 / sqrt(3)"),
    # -- paper 000: meshfree thin walls --------------------------------------------------------------
    Case("000-plate-impact-petals-quick", "000", "quick", "plate-impact",
         "petals of the 10 mm Al plate perforated by the sphere at 300 m/s", "petals", "", (0.0, 0.0),
         "crackle's own count at every resolution it ran (quick, 15 mm, graded 3.5 mm): 0, a plug", "4 petals",
         reason="crackle perforates the plate by a plug at every resolution it ran, the sphere free or deformable "
                "(docs/validation.md, paper 000 section 4.2); petalling is issue 70"),
    # -- paper 001: FDEM ------------------------------------------------------------------------------
    Case("001-sphere-fast-energy", "001", "quick", "sphere-impact-fast", "energy error of the 100 m/s sphere impact",
         "energy_error", "%", (-3.0, 3.0), "the acceptance for violent runs: |energy error| < 3 %", "(not reported)",
         scale=100.0),
    Case("001-3pb-peak-quick", "001", "quick", "three-point-bending", "peak load on the top platen, h = 25 mm",
         "peak_forces.top", "N", (624.0, 762.0),
         "crackle's own value, 693 N, +-10 %: the paper gives no number, only that its coarse meshes over-estimate "
         "the converged peak by < 8 %", "coarse meshes within +8 % of the converged peak",
         reason="crackle's coarse mesh under-estimates its own converged peak (832.8 N at h = 5 mm) by 17 %, where "
                "the paper's coarse meshes over-estimate theirs by < 8 % (docs/validation.md, paper 001, "
                "three-point bending)"),
    Case("001-brazilian-0-quick", "001", "quick", "brazilian-disc", "Brazilian disc's peak load, theta = 0",
         "peak_force", "N", (3044.0, 3720.0),
         "crackle's own quick value, 3382 N, +-10 % (the quick disc's peaks over loading angles and half the platen "
         "speed: 3227-3382 N)", "2130-2266 N (mean 2220, CV 2.4 %)",
         reason="the paper's mean is 0.79 ft by the elastic Brazilian relation, below the tensile strength it gave "
                "its rock: faces that open at ft split the disc at ~ft (crackle at the paper's 1.2 mm mesh: 1.05 ft, "
                "2968 N over four angles, CV 4.0 %); the quick 4 mm tets add about 15 % (docs/validation.md, paper "
                "001 section 4)"),
    # -- paper 002: Kirchhoff-Love shell ------------------------------------------------------------
    Case("002-centre-crack-j-quick", "002", "quick", "shell-centre-crack",
         "J of the centre crack (2a/2b = 0.5, 100 MPa) over K^2 / E", "j_ratio", "", (0.80, 0.90),
         "closed form K^2 / E = 5,526 J/m^2 (Tada's K = 1.186 sigma sqrt(pi a)); constant-strain triangles reach it "
         "at first order in the cell size (0.849 at the quick 5 mm cells, 0.937 at 2.5 mm, 1.0004 extrapolated): "
         "the quick value +-5 %", "K^2 / E"),
    Case("002-centre-crack-j-full", "002", "full", "shell-centre-crack",
         "J of the centre crack at 2.5 mm cells over K^2 / E", "j_ratio", "", (0.90, 0.97),
         "closed form K^2 / E as above; 0.937 at 2.5 mm cells, first order in the cell size: +-3 %", "K^2 / E"),
    # -- paper 003: DEM -------------------------------------------------------------------------------
    Case("003-ucs-quick", "003", "quick", "dem-ucs", "uniaxial compressive strength", "peak_stress", "MPa",
         (59.0, 75.0),
         "crackle's quick sample over twelve round-off draws: 59.4-73.8 MPa (docs/validation.md, paper 003); the "
         "paper's two samples (~70 MPa, 5 % apart) lie inside", "~70 MPa", scale=1e-6),
    Case("003-modulus-quick", "003", "quick", "dem-ucs", "Young's modulus from the platen (20-50 % of the peak)",
         "platen_modulus", "GPa", (49.5, 60.5),
         "the paper's ~55 GPa read from its stress-strain curve, +-10 % (it gives no scatter); crackle's draws "
         "scatter by 0.5 %", "~55 GPa", scale=1e-9),
    Case("003-brazilian-quick", "003", "quick", "dem-brazilian", "Brazilian tensile strength 2F / (pi D t)",
         "brazilian_strength", "MPa", (3.76, 4.60),
         "crackle's own value, 4.18 MPa, +-10 % (the UCS's round-off scatter on the same packings)", "~6 MPa",
         scale=1e-6,
         reason="the full form reads 4.37 MPa (-27 %) and the quick 4.18: the bonds' strengths are the paper's, the "
                "packing's density and contacts are not (docs/validation.md, 'Full forms at the paper's density')"),
    Case("003-open-flaw-90-quick", "003", "quick", "dem-flaw", "strength with an open flaw at theta = 90 deg",
         "peak_stress", "MPa", (58.4, 71.4), "crackle's own quick value, 64.9 MPa (2026-12-06), +-10 % (round-off "
         "scatter)", "56 MPa", overrides={"flaw.angle": 90}, scale=1e-6,
         reason="the quick sample reads 16 % above the paper, as its intact strength rises with the particle size "
                "(docs/validation.md, paper 003, the UCS rows); the full form reads 57.3 MPa, +2 % (003-open-flaw-90-full)"),
    Case("003-open-flaw-90-full", "003", "full", "dem-flaw", "strength with an open flaw at theta = 90 deg "
         "(20,538 particles)", "peak_stress", "MPa", (47.6, 64.4),
         "the paper's 56 MPa (Fig. 9-10), +-15 %: crackle's round-off scatter (~5 % a draw) and the paper's two "
         "intact samples 5 % apart; crackle's full form read 57.3 MPa (2026-11-27)", "56 MPa",
         overrides={"flaw.angle": 90}, scale=1e-6),
    Case("003-open-flaw-0-quick", "003", "quick", "dem-flaw", "strength with an open flaw at theta = 0",
         "peak_stress", "MPa", (36.4, 44.5), "crackle's own quick value, 40.5 MPa (2026-12-06), +-10 % (round-off "
         "scatter)",
         "29 MPa", overrides={"flaw.angle": 0}, scale=1e-6,
         reason="the 0-deg flaw weakens crackle's sample less than the paper's (0.58 of the intact strength against "
                "0.41; full form 35.0 MPa, 2026-11-27): neither the particle size nor the slot's width closes it "
                "(docs/validation.md, paper 003)"),
    Case("003-ucs-full", "003", "full", "dem-ucs", "uniaxial compressive strength (20,703 particles)",
         "peak_stress", "MPa", (55.0, 66.0),
         "crackle's three full-form runs, 58.0 / 62.0 / 61.0 MPa, and their round-off scatter (+-5 %)", "~70 MPa",
         scale=1e-6,
         reason="the full form reads 60.3 MPa on average, -14 %, at the paper's particle size and density "
                "(docs/validation.md, 'Full forms at the paper's density')"),
    Case("003-modulus-full", "003", "full", "dem-ucs", "Young's modulus from the platen (20,703 particles)",
         "platen_modulus", "GPa", (49.5, 60.5),
         "the paper's ~55 GPa read from its stress-strain curve, +-10 %; crackle's full runs 55.6 and 55.7 GPa",
         "~55 GPa", scale=1e-9),
    Case("003-brazilian-full", "003", "full", "dem-brazilian", "Brazilian tensile strength (16,035 particles)",
         "brazilian_strength", "MPa", (3.9, 4.8), "crackle's full-form 4.37 MPa, +-10 % (round-off scatter)",
         "~6 MPa", scale=1e-6,
         reason="-27 % at the paper's particle size and density, with the UCS's -14 % (docs/validation.md)"),
    Case("003-tension-full", "003", "full", "dem-tension", "direct tensile strength (20,703 particles)",
         "nominal_strength", "MPa", (4.35, 5.3), "crackle's full-form 4.84 MPa, +-10 % (round-off scatter)",
         "~6 MPa", scale=1e-6,
         reason="-19 %: the bonds fail at their own strength t = 4.5 MPa (ratio 1.075), below the paper's UTS "
                "(docs/validation.md, paper 003)"),
    # -- paper 004: nuts ------------------------------------------------------------------------------
    Case("004-walnut-crush-quick", "004", "quick", "walnut-crush", "uniaxial crush peak force", "peak_force", "N",
         (217.6, 266.0),
         "crackle's own quick value, 241.8 N, +-10 % (the quick mesh's peaks over code changes 241.8-244.6 N; "
         "219-228 N between 40 and 200 mm/s)", "~237 N (converged, 0.95 mm)",
         reason="the quick 3 mm mesh at 1.25 m/s reads 242 N, but the agreement does not carry to the converged "
                "mesh: at 1.0 and 0.95 mm and the paper's 40 mm/s crackle reads 182-186 N, 0.77 of the paper's "
                "(docs/validation.md, paper 004)"),
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
