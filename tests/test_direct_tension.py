"""Direct tension with glued grips (the shipped `direct-tension` example and the glued-tool
contact it uses).

Closed forms: an elastic bar pulled by glued grips carries F = E A (elongation) / L; a bar far
shorter than the characteristic length E Gf / ft^2 (40 mm against 144 mm) breaks at a nominal
stress equal to the tensile strength ft where faces normal to the pull exist (a structured mesh).
On an unstructured mesh every separating surface is a zigzag of faces inclined to the pull, and
the Guo-Munjiza law opens a face on its normal traction alone: measured here, it is the
face-restricted crack's strength bias (docs/validation.md, "Strength objectivity").
"""

from __future__ import annotations

import numpy as np
import pytest

from crackle.api import run_scenario

E, A, L = 26e9, 1e-4, 0.04


def test_glued_grips_pull_an_elastic_bar(tmp_path):
    """A structured 40 x 10 x 10 mm bar (768 tets) with strong extrinsic faces (none inserts)
    pulled by the example's two glued grips to 0.2 ms: the grip force is E A (u_right - u_left) / L
    within 3 % (measured -1.5 %: the grips' penalty ties add h / (10 L) of compliance each, the
    glued ends' blocked Poisson contraction a little stiffness), both grips carry it (within
    1 %), and the energy audit closes within 0.5 %."""
    result = run_scenario("direct-tension", tmp_path, progress=False, overrides=[
        "specimen.mesh=structured", "specimen.element_size=0.005", "material.interface.insertion=extrinsic",
        "material.interface.tensile_strength=1e9", "run.end_time=2e-4", "run.field_frames=0"])
    h = np.genfromtxt(tmp_path / "history.csv", delimiter=",", names=True)
    late = h["time"] >= 1.5e-4  # past the ramp's ringing: mean over the last 50 us
    elongation = np.mean(h["toolrightux"][late] - h["toolleftux"][late])
    right, left = np.mean(h["toolrightfx"][late]), np.mean(h["toolleftfx"][late])
    print(f"grip force {right:.1f} / {left:.1f} N against E A du / L = {E * A * elongation / L:.1f} N")
    assert result.summary["broken"] == 0
    assert right == pytest.approx(E * A * elongation / L, rel=0.03)  # tool.NAME.f: the force on the specimen
    assert left == pytest.approx(-right, rel=0.01)
    assert abs(result.summary["energy_error"]) < 0.005


def test_structured_bar_breaks_at_the_tensile_strength(tmp_path):
    """With faces normal to the pull (structured cells), the quick bar's nominal strength is ft:
    tensile_strength_ratio within 3 % of 1 (measured 1.008, extrinsic faces, 768 tets)."""
    result = run_scenario("direct-tension", tmp_path, quick=True, progress=False, overrides=[
        "specimen.mesh=structured", "material.interface.insertion=extrinsic", "run.field_frames=0"])
    s = result.summary
    assert s["loaded_area"] == pytest.approx(A, rel=1e-9)
    assert s["nominal_strength"] == pytest.approx(s["peak_forces"]["right"] / A, rel=1e-9)  # the first pulling grip
    assert s["tensile_strength_ratio"] == pytest.approx(1.0, abs=0.03)


@pytest.mark.parametrize("insertion, measured", [("intrinsic", 1.024), ("extrinsic", 1.092)])
def test_effective_mixed_mode_breaks_the_bar_at_ft(tmp_path, insertion, measured):
    """The face-restricted bias and its remedy. With paper 001's Mohr-Coulomb law the quick
    unstructured bar (420 tets) peaks at 1.30 ft intrinsic and 1.35 ft extrinsic (1.3-1.5 ft at
    every size and orientation measured: docs/validation.md, "Strength objectivity"): a face
    inclined at theta to the crack plane opens only when sigma cos^2 theta reaches ft. With
    mixed_mode = "effective" (Camacho-Ortiz: in tension the traction magnitude meets ft, and the
    slip shares the damage) the inclined faces open with the crack: tensile_strength_ratio within
    10 % of 1 in both insertion modes (measured 1.024 intrinsic, 1.092 extrinsic: its peak is the
    grip's ring as the bar separates; the plateau before it is 0.99 ft), and the energy audit
    closes within 1 % (measured 0.13 % / -0.08 %)."""
    result = run_scenario("direct-tension", tmp_path, quick=True, progress=False, overrides=[
        f"material.interface.insertion={insertion}", "material.interface.mixed_mode=effective",
        "run.field_frames=0"])
    s = result.summary
    print(f"{insertion}: tensile_strength_ratio {s['tensile_strength_ratio']:.3f} (measured {measured})")
    assert s["tensile_strength_ratio"] == pytest.approx(1.0, abs=0.10)
    assert s["broken"] > 0
    assert abs(s["energy_error"]) < 0.01
