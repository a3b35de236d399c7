"""Direct tension with glued grips (the shipped `direct-tension` example and the glued-tool
contact it uses).

Closed forms: an elastic bar pulled by glued grips carries F = E A (elongation) / L; a bar far
shorter than the characteristic length E Gf / ft^2 (40 mm against 144 mm) breaks at a nominal
stress equal to the tensile strength ft where faces normal to the pull exist (a structured mesh).
On an unstructured mesh every separating surface is a zigzag of faces inclined to the pull:
paper 001's Mohr-Coulomb law opens a face on its normal traction alone, which makes the bar
stronger than ft (the face-restricted crack's strength bias); the example's effective mixed mode
opens it on its traction's magnitude (docs/validation.md, "Strength objectivity").
"""

from __future__ import annotations

import numpy as np
import pytest

from crackle.api import run_scenario
from crackle.scenario import ScenarioError, load_scenario

# The runs here leave out plots/ (seconds a run, read by no test here): the same steps and outputs.

E, A, L = 26e9, 1e-4, 0.04


def test_glued_grips_pull_an_elastic_bar(tmp_path):
    """A structured 40 x 10 x 10 mm bar (768 tets) with strong extrinsic faces (none inserts)
    pulled by the example's two glued grips to 0.2 ms: the grip force is E A (u_right - u_left) / L
    within 3 % (measured -1.5 %: the grips' penalty ties add h / (10 L) of compliance each, the
    glued ends' blocked Poisson contraction a little stiffness), both grips carry it (within
    1 %), and the energy audit closes within 0.5 %."""
    result = run_scenario("direct-tension", tmp_path, progress=False, plots=False, overrides=[
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


MOVING_SUPPORTS = """
method = "fdem"
[specimen]
shape = "box"
size = [0.04, 0.01, 0.01]
element_size = 0.005
mesh = "structured"
[material]
density = 2340.0
youngs_modulus = 26e9
poissons_ratio = 0.2
[material.interface]
law = "guo-munjiza"
tensile_strength = 1e9
cohesion = 15e9
friction_angle = 30.0
fracture_energy = 50.0
insertion = "extrinsic"
[[supports]]
kind = "fixed"
where = { plane_point = [0.0, 0.0, 0.0], plane_normal = [1.0, 0.0, 0.0] }
[[supports]]
name = "grip"
kind = "roller"
normal = [1.0, 0.0, 0.0]
speed = 0.05
ramp_time = 5e-5
where = { plane_point = [0.04, 0.0, 0.0], plane_normal = [1.0, 0.0, 0.0] }
[run]
end_time = 2e-4
field_frames = 0
"""


def test_moving_support_pulls_an_elastic_bar(tmp_path):
    """The bar of the glued-grip test, its left face fixed and its right face a roller support
    moving along x (a velocity boundary condition): the support's reaction (tool.grip.fx, read by
    the load cell) is E A u / L within 2 % (measured -0.9 %, the mean over the last 50 us), its
    displacement the ramp's integral, the energy audit closes within 1e-4 (measured -7e-8: the
    support's work is counted from its reaction) and the summary takes the support as the
    pulling grip (nominal_strength = peak reaction / section)."""
    scenario = tmp_path / "bar.toml"
    scenario.write_text(MOVING_SUPPORTS)
    result = run_scenario(str(scenario), tmp_path / "out", progress=False, plots=False)
    h = np.genfromtxt(tmp_path / "out" / "history.csv", delimiter=",", names=True)
    late = h["time"] >= 1.5e-4
    elongation = np.mean(h["toolgripux"][late])
    force = np.mean(h["toolgripfx"][late])
    print(f"support reaction {force:.1f} N against E A u / L = {E * A * elongation / L:.1f} N")
    assert force == pytest.approx(E * A * elongation / L, rel=0.02)
    assert h["toolgripux"][-1] == pytest.approx(0.05 * (2e-4 - 2.5e-5), rel=1e-3)
    s = result.summary
    assert abs(s["energy_error"]) < 1e-4
    assert s["nominal_strength"] == pytest.approx(s["peak_forces"]["grip"] / A, rel=1e-9)


@pytest.mark.parametrize("support, message", [
    ('kind = "fixed"\nspeed = 0.1', "needs direction"),
    ('kind = "fixed"\nname = "pull"', "only for a moving support"),
])
def test_moving_support_keys_are_checked(tmp_path, support, message):
    """A fixed support with a speed needs a direction; a name (or a direction or ramp) on a
    support that holds still is refused, naming the key."""
    text = MOVING_SUPPORTS.replace('kind = "fixed"', support, 1)
    scenario = tmp_path / "bar.toml"
    scenario.write_text(text)
    with pytest.raises(ScenarioError, match=message):
        load_scenario(str(scenario))


@pytest.mark.slow
def test_structured_bar_breaks_at_the_tensile_strength(tmp_path):
    """With faces normal to the pull (structured cells), the quick bar's nominal strength is ft:
    tensile_strength_ratio within 3 % of 1 (measured 1.008, extrinsic faces, 768 tets)."""
    result = run_scenario("direct-tension", tmp_path, quick=True, progress=False, plots=False, overrides=[
        "specimen.mesh=structured", "material.interface.insertion=extrinsic", "run.field_frames=0"])
    s = result.summary
    assert s["loaded_area"] == pytest.approx(A, rel=1e-9)
    assert s["nominal_strength"] == pytest.approx(s["peak_forces"]["right"] / A, rel=1e-9)  # the first pulling grip
    assert s["tensile_strength_ratio"] == pytest.approx(1.0, abs=0.03)


@pytest.mark.parametrize("insertion, measured", [("intrinsic", 1.041), ("extrinsic", 1.090)])
@pytest.mark.slow
def test_quick_bar_breaks_at_ft_in_both_insertion_modes(tmp_path, insertion, measured):
    """The shipped quick bar (420 unstructured tets, mixed_mode = "effective"): a face inclined
    to the crack plane opens when the magnitude of its traction reaches ft (Camacho-Ortiz), so
    tensile_strength_ratio is within 10 % of 1 in both insertion modes (measured 1.041 intrinsic,
    1.090 extrinsic: the best-aligned faces of this coarse mesh sit ~20 deg off the section, and
    an extrinsic face is checked on its tets' traction, sigma cos(theta)); past the peak the bar
    softens (the grip force ends under half its peak: 0.14 / 0.18 of it at 0.6 ms, on the cohesive
    tail: no face has reached the critical opening, 43 um, by then) and the energy audit closes
    within 1 % (measured -0.38 % / -0.04 %)."""
    result = run_scenario("direct-tension", tmp_path, quick=True, progress=False, plots=False, overrides=[
        f"material.interface.insertion={insertion}", "run.field_frames=0"])
    s = result.summary
    print(f"{insertion}: tensile_strength_ratio {s['tensile_strength_ratio']:.3f} (measured {measured})")
    assert s["tensile_strength_ratio"] == pytest.approx(1.0, abs=0.10)
    h = np.genfromtxt(tmp_path / "history.csv", delimiter=",", names=True)
    assert h["toolrightfx"][-1] < 0.5 * s["peak_forces"]["right"]
    assert abs(s["energy_error"]) < 0.01


@pytest.mark.slow
def test_paper_law_carries_the_face_orientation_bias(tmp_path):
    """The bias the effective mixed mode removes. With paper 001's Mohr-Coulomb law a face opens
    only when its own normal traction reaches ft, sigma cos^2(theta) on a face at theta to the
    section: the same quick bar peaks at 1.296 ft intrinsic (1.3-1.6 ft at every size and
    orientation measured: docs/validation.md, "Strength objectivity"). Checked: above 1.2 ft,
    and the run's summary carries set-up's warning about it."""
    result = run_scenario("direct-tension", tmp_path, quick=True, progress=False, plots=False, overrides=[
        "material.interface.mixed_mode=paper", "run.field_frames=0"])
    ratio = result.summary["tensile_strength_ratio"]
    print(f"paper 001's law: tensile_strength_ratio {ratio:.3f} (measured 1.296)")
    assert ratio > 1.2
    # and set-up said so, in the summary as on the screen
    assert any('mixed_mode = "paper" on an unstructured mesh' in w for w in result.summary["warnings"])
