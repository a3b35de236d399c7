"""One-element and scenario tests of the linear cohesive law (Camacho & Ortiz 1996; Akantu's
cohesive_linear), on the two-tet `Cell` of tests/fdem/test_fdem_law.py (openings prescribed, the
law evaluated by `interface_forces`). The expected numbers come from the law's definition:

* effective opening delta = sqrt(<dn>^2 + beta^2 ds^2), effective traction pn delta up to
  sigma_c at delta_0 = sigma_c / pn, then linear to zero at delta_c = 2 G_c / sigma_c;
* tractions tn = (t / delta) dn and ts = beta^2 (t / delta) ds: along any opening direction the
  traction's peak lies on (tn / sigma_c)^2 + (ts / (beta sigma_c))^2 = 1, and a full failure
  dissipates G_c per unit area whatever the direction;
* pn = penalty_factor E / h, ps = beta^2 pn.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from crackle.fdem.laws import BilinearLaw, LinearLaw
from crackle.materials import Material
from crackle.scenario import load_scenario

from fdem_helpers import E, NU, RHO
from test_bilinear_law import drive, path_to
from test_fdem_law import Cell

SIGMA_C = 3e6  # Pa
GC = 10.0  # J/m^2
BETA = 0.5


def block(**overrides) -> Material:
    law = dict(tensile_strength=SIGMA_C, fracture_energy=GC, shear_ratio=BETA)
    law.update(overrides)
    return Material(RHO, E, NU, LinearLaw(**law), name="block")


def test_its_row_is_the_bilinear_row_of_the_same_law():
    """sigma_c, G_c, beta are the bilinear law with ts0 = beta sigma_c, GIc = GIIc = G_c and the
    quadratic initiation: the two table rows are equal in every column, so the bilinear law's
    compiled pieces step it."""
    linear = LinearLaw(SIGMA_C, GC, shear_ratio=BETA, friction=0.3, insertion="extrinsic")
    same = BilinearLaw(SIGMA_C, BETA * SIGMA_C, GC, 1e13, BETA**2 * 1e13, friction=0.3, insertion="extrinsic")
    assert np.array_equal(linear.table_row(), same.table_row())


def test_penalties_are_per_element():
    """pn = 200 E / h (intrinsic; 2 E / h extrinsic) with h the smaller altitude onto the face, and
    ps = beta^2 pn, to 1e-12."""
    cell = Cell(block())
    altitude = float(np.min(3.0 * cell.model.tets.vol / cell.A))
    assert cell.pn == pytest.approx(200.0 * E / altitude, rel=1e-12)
    assert cell.ps == pytest.approx(BETA**2 * cell.pn, rel=1e-12)
    assert Cell(block(insertion="extrinsic")).pn == pytest.approx(2.0 * E / altitude, rel=1e-12)


@pytest.mark.parametrize("angle", [0.0, 45.0, 90.0])
def test_peak_on_the_ellipse_and_gc_dissipated_in_any_direction(angle):
    """Opening along (cos, sin) of `angle` in the (dn, ds) plane, monotonic past delta_c: the
    largest traction lies on (tn / sigma_c)^2 + (ts / (beta sigma_c))^2 = 1 within 1 %, and the
    damage booked at failure is G_c A within 2 % (the same G_c in pure mode I, mixed and pure
    mode II)."""
    cell = Cell(block())
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    # The path's length along (c, s) at which the effective opening reaches delta_0 and delta_c.
    per_unit = math.hypot(c, BETA * s)
    d0 = SIGMA_C / cell.pn / per_unit
    dc = 2.0 * GC / SIGMA_C / per_unit
    sig, tau, _, _ = drive(cell, path_to(d0, dc), (c, s))
    on_ellipse = np.sqrt((sig / SIGMA_C) ** 2 + (tau / (BETA * SIGMA_C)) ** 2)
    print(f"{angle} deg: peak {on_ellipse.max():.5f} of the ellipse, e_damage / (G_c A) = {cell.e_damage / (GC * cell.A):.5f}")
    assert on_ellipse.max() == pytest.approx(1.0, rel=0.01)
    assert cell.e_damage == pytest.approx(GC * cell.A, rel=0.02)


def test_a_scenario_picks_it_by_name(tmp_path):
    """[material.interface] law = "linear" in a scenario: its keys, and a key of another law named
    as such."""
    text = """method = "fdem"
[specimen]
shape = "box"
size = [0.02, 0.01, 0.01]
element_size = 0.005
[material]
density = 2340.0
youngs_modulus = 26e9
poissons_ratio = 0.2
[material.interface]
law = "linear"
tensile_strength = 3e6
fracture_energy = 10.0
shear_ratio = 0.5
insertion = "extrinsic"
[run]
end_time = 1e-6
"""
    path = tmp_path / "linear.toml"
    path.write_text(text)
    scenario, _ = load_scenario(str(path))
    assert isinstance(scenario.material.interface, LinearLaw) and scenario.material.interface.shear_ratio == 0.5
    path.write_text(text.replace("shear_ratio = 0.5", "cohesion = 15e6"))
    with pytest.raises(Exception, match='cohesion is a key of the guo-munjiza interface, not of the linear one'):
        load_scenario(str(path))
