"""Random fracture properties per site for the meshfree particles and the shell's edges
([material.random]): the drawn values follow the requested distribution, the same run.seed draws
the same values and another seed others, each method's criterion reads each site's own value
(a particle's threshold, the Gc of the edge ahead of a shell's crack tip), the shell's values
follow the edges through cuts and moves, a uniform model keeps its one value, and runs with
drawn values stay bit-identical with 1 and 2 numba threads."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from dataclasses import replace

import meshio
import numpy as np
import pytest
from scipy import stats

from crackle.cli import main
from crackle.materials.random_properties import RandomProperty, standard_normal, stream_seed, to_marginal
from crackle.meshfree import build_simulation as build_meshfree
from crackle.scenario import load_scenario
from crackle.shell import build_simulation as build_shell
from crackle.materials.random_properties import hashed_normal
from crackle.shell.growth import RandomSites, SiteField, align_ahead, edge_midpoints, step_ahead

WEIBULL = '{distribution="weibull", modulus=6}'
# The quick plate impact's aluminium: a particle fails at 3 x 150 MPa (material.fracture_factor).
PLATE = "aluminium (paper 000, section 4.2)"


def _meshfree(example, *settings, seed=0):
    scenario, base = load_scenario(example, quick=True, overrides=[*settings, f"run.seed={seed}"])
    return build_meshfree(scenario, base), scenario


def _centre_crack(*settings, seed=0):
    scenario, base = load_scenario("shell-centre-crack", quick=True, overrides=[*settings, f"run.seed={seed}"])
    return build_shell(scenario, base)


def _within_three_standard_errors(values, dist):
    return abs(values.mean() - dist.mean()) < 3.0 * dist.std() / np.sqrt(len(values))


# --- meshfree: thresholds per particle ---------------------------------------------------------


@pytest.mark.parametrize("example, prop, table, mean", [
    ("plate-impact", "tensile_strength", WEIBULL, 150e6),
    ("plate-tearing", "failure_plastic_strain", '{distribution="lognormal", cv=0.3}', 0.1),
])
def test_meshfree_thresholds_follow_the_distribution_and_the_seed(example, prop, table, mean):
    """The quick plate impact with Weibull (m = 6) tensile strengths and the quick plate tearing
    with lognormal (CV 0.3) failure plastic strains, drawn per particle: the link breaking's
    thresholds are the drawn values (x fracture_factor for the strength), with the requested
    mean within 3 standard errors and KS p > 0.01 against the marginal; the summary's statistics
    are theirs; the same run.seed draws the same values, another seed others."""
    spec = RandomProperty(**_table(table))
    sim, scenario = _meshfree(example, f"material.random.{prop}={table}")
    n = sim.body_start[1]
    values = sim.drawn[prop]
    assert len(values) == n
    b = sim.breaking
    if prop == "tensile_strength":
        assert np.array_equal(b.fracture_stress[:n], scenario.material.fracture_factor * values)
    else:
        assert np.array_equal(b.failure_strain[:n], values)
    dist = spec.marginal(mean)
    assert _within_three_standard_errors(values, dist)
    assert stats.kstest(values, dist.cdf).pvalue > 0.01
    reported = sim.random_properties[scenario.material.name][prop]
    assert reported["sites"] == n and reported["mean"] == pytest.approx(values.mean(), rel=1e-12)
    assert np.array_equal(_meshfree(example, f"material.random.{prop}={table}")[0].drawn[prop], values)
    other = _meshfree(example, f"material.random.{prop}={table}", seed=1)[0].drawn[prop]
    assert not np.allclose(other, values)


def _table(text: str) -> dict:
    import tomllib

    return tomllib.loads(f"x = {text}")["x"]


def test_meshfree_uniform_thresholds_are_the_material_value():
    """Without [material.random], or with an empty one, every particle's fracture stress is
    3 x 150 MPa exactly (the scalar the criterion compared before) and no failure strain is set;
    nothing is drawn and the summary says None."""
    for settings in ((), ("material.random={}",)):
        sim, _ = _meshfree("plate-impact", *settings)
        n = sim.body_start[1]
        assert np.all(sim.breaking.fracture_stress[:n] == 3.0 * 150e6)
        assert np.all(sim.breaking.failure_strain == np.inf)
        assert sim.drawn == {} and sim.summary()["random_properties"] is None


def test_meshfree_criterion_reads_each_particles_threshold():
    """A uniaxial Cauchy stress equal to the median of the drawn fracture stresses on every
    particle fails exactly the particles whose own threshold is below it (about half), and an
    equivalent plastic strain at the median of the drawn failure strains fails those whose
    failure strain it reaches: the criterion reads the per-particle arrays."""
    sim, _ = _meshfree("plate-impact", f"material.random.tensile_strength={WEIBULL}",
                       "material.failure_plastic_strain=0.2",
                       'material.random.failure_plastic_strain={distribution="normal", cv=0.2}')
    b, p = sim.breaking, sim.particles
    n = len(p.x)
    level = _between_the_middle_two(b.fracture_stress)
    cauchy = np.zeros((n, 6))
    cauchy[:, 0] = level
    ids, normals = b.newly_failed(cauchy, p.deformation, cauchy)
    expected = np.flatnonzero(b.fracture_stress < level)
    assert np.array_equal(ids, expected) and 0.4 * n < len(ids) < 0.6 * n
    assert np.allclose(np.abs(normals[:, 0]), 1.0)  # the crack plane normal to the pull
    strain = _between_the_middle_two(b.failure_strain)
    ids, _ = b.newly_failed(np.zeros((n, 6)), p.deformation, np.zeros((n, 6)), np.full(n, strain))
    assert np.array_equal(ids, np.flatnonzero(b.failure_strain < strain)) and 0.4 * n < len(ids) < 0.6 * n


def _between_the_middle_two(values) -> float:
    """A level halfway between the two middle values (no site exactly at it)."""
    ordered = np.sort(values)
    return float(0.5 * (ordered[len(values) // 2 - 1] + ordered[len(values) // 2]))


def test_meshfree_summary_and_fields_carry_the_draws(tmp_path):
    """The quick plate impact for 2 us with Weibull strengths in a random field: summary.json's
    random_properties has the drawn values' statistics under the material's name (the mean near
    150 MPa, the realised correlation length reported), and the VTU's point data
    `tensile_strength` holds each particle's value."""
    out = tmp_path / "run"
    assert main(["run", "plate-impact", "--quick", "--out", str(out), "--set", "run.end_time=2e-6", "--set",
                 "run.field_frames=1", "--set",
                 'material.random.tensile_strength={distribution="weibull", modulus=6, correlation_length=0.04}']) == 0
    drawn = json.loads((out / "summary.json").read_text())["random_properties"][PLATE]["tensile_strength"]
    assert drawn["distribution"] == "weibull" and drawn["sites"] == 1323
    assert drawn["correlation_length"] == 0.04 and drawn["correlation_length_realised"] > 0.0
    assert 100e6 < drawn["mean"] < 200e6
    mesh = meshio.read(sorted((out / "fields").glob("*.vtu"))[-1])
    values = mesh.point_data["tensile_strength"]
    assert len(values) == 1323 and values.max() == pytest.approx(drawn["max"], rel=1e-12)
    assert values.mean() == pytest.approx(drawn["mean"], rel=1e-9)


@pytest.mark.parametrize("settings, message", [
    (["material.random.cohesion=" + WEIBULL], "tensile_strength, failure_plastic_strain"),
    (["material.random.failure_plastic_strain=" + WEIBULL], "inf"),
])
def test_meshfree_bad_random_properties_are_refused(tmp_path, capsys, settings, message):
    """A property the meshfree method does not draw, or one whose mean is off (inf): exit 2
    naming material.random and the fix."""
    args = ["run", "plate-impact", "--quick", "--out", str(tmp_path / "x")]
    for s in settings:
        args += ["--set", s]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "random" in err and message in err


# --- shell: Gc per edge, strength per vertex ---------------------------------------------------


def test_shell_edge_toughness_follows_the_distribution_and_the_seed():
    """The quick centre crack with Weibull (m = 6) Gc per edge (independent sites): the edges'
    values have the requested mean within 3 standard errors and KS p > 0.01; summary.json's
    statistics are over the set-up's edges; the same run.seed gives the same values, another
    seed others; without [material.random] every edge's Gc is fracture.toughness."""
    sim = _centre_crack("fracture.toughness=300", f"material.random.toughness={WEIBULL}")
    mesh = sim.shell.mesh
    values = sim.growth.edge_toughness(mesh, np.arange(len(mesh.edge)))
    dist = RandomProperty(distribution="weibull", modulus=6.0).marginal(300.0)
    assert _within_three_standard_errors(values, dist)
    assert stats.kstest(values, dist.cdf).pvalue > 0.01
    reported = sim.summary()["random_properties"]["steel"]["toughness"]
    assert reported["sites"] == len(mesh.edge) and reported["mean"] == pytest.approx(values.mean(), rel=1e-12)
    again = _centre_crack("fracture.toughness=300", f"material.random.toughness={WEIBULL}")
    assert np.array_equal(again.growth.edge_toughness(mesh, np.arange(len(mesh.edge))), values)
    other = _centre_crack("fracture.toughness=300", f"material.random.toughness={WEIBULL}", seed=1)
    assert not np.allclose(other.growth.edge_toughness(mesh, np.arange(len(mesh.edge))), values)
    uniform = _centre_crack("fracture.toughness=300")
    assert uniform.growth.sites is None and uniform.summary()["random_properties"] is None
    assert np.all(uniform.growth.edge_toughness(mesh, np.arange(len(mesh.edge))) == 300.0)


def test_shell_site_values_are_functions_of_position():
    """A SiteField's values depend on the point alone: the same points in another order and
    among others give the same values, also from a pickled copy (a checkpoint); a correlated field is materials.random_properties'
    (standard_normal at the same points and stream, mapped through the marginal) bit for bit;
    independent hashed values are standard normal (KS p > 0.01) and a moved point draws anew."""
    points = np.random.default_rng(3).random((400, 3)) * 0.1
    spec = RandomProperty(distribution="normal", cv=0.2, correlation_length=0.02)
    seed = stream_seed(7, "steel", "toughness")
    field = SiteField(spec, 300.0, seed)
    values = field(points)
    assert np.array_equal(values, to_marginal(spec, 300.0, standard_normal(spec, points, seed)))
    fresh = pickle.loads(pickle.dumps(field))  # a checkpoint's copy: the definition, no remembered values
    assert fresh._known == {} and fresh._field is None
    order = np.random.default_rng(4).permutation(400)
    mixed = np.concatenate([points[order], np.random.default_rng(5).random((50, 3))])
    assert np.array_equal(fresh(mixed)[:400], values[order])
    z = hashed_normal(points, seed)
    assert np.array_equal(hashed_normal(points[order], seed), z[order])
    assert stats.kstest(z, "norm").pvalue > 0.01
    assert not np.any(hashed_normal(points * (1.0 + 1e-12), seed) == z)
    assert not np.any(hashed_normal(points, seed + 1) == z)


def test_shell_values_follow_the_edges_through_cuts_and_moves():
    """The quick centre crack with Gc in a random field: after a cut (cut_edge rebuilds and
    renumbers the edges) every edge's Gc is the one of the set-up edge with the same reference
    mid-point (the cut edge's two faces both keep its value); after align_ahead moves the tip's
    neighbours, the moved edges take the field's value at their new mid-points (the value a
    fresh field gives there) and the others keep theirs."""
    sim = _centre_crack("fracture.toughness=300",
                        'material.random.toughness={distribution="normal", cv=0.3, correlation_length=0.01}')
    growth = sim.growth
    mesh = sim.shell.mesh
    edges = len(mesh.edge)
    before = dict(zip(map(bytes, edge_midpoints(mesh, np.arange(len(mesh.edge)))),
                      growth.edge_toughness(mesh, np.arange(len(mesh.edge)))))
    tip = sim.tips[0]
    vertex, _ = step_ahead(sim.shell, tip.vertex, tip.direction)
    cut_gc = sim._edge_gc(tip.vertex, vertex)
    sim._cut(tip.vertex, vertex, 1e-7)
    mesh = sim.shell.mesh
    assert len(mesh.edge) == edges + 1
    mid = edge_midpoints(mesh, np.arange(len(mesh.edge)))
    after = growth.edge_toughness(mesh, np.arange(len(mesh.edge)))
    assert np.array_equal(after, [before[bytes(m)] for m in mid])
    assert np.sum(after == cut_gc) >= 2
    # A turn of the edges at the new tip towards 30 deg off the crack's line moves its neighbours.
    heading = np.array([np.cos(np.radians(30.0)), np.sin(np.radians(30.0)), 0.0])
    moved = align_ahead(sim.shell, vertex, heading, sim._thinnest)
    assert moved is not None
    mid_moved = edge_midpoints(moved.mesh, np.arange(len(moved.mesh.edge)))
    values = growth.edge_toughness(moved.mesh, np.arange(len(moved.mesh.edge)))
    changed = np.any(mid_moved != mid, axis=1)
    assert changed.any() and np.array_equal(values[~changed], after[~changed])
    site = growth.sites.fields["toughness"][0]
    assert np.array_equal(values[changed], SiteField(site.spec, site.mean, site.seed)(mid_moved[changed]))


def test_shell_growth_reads_the_gc_of_the_edge_ahead():
    """The quick centre crack suddenly loaded (Gc far above J, no growth) for 300 steps; then a
    Griffith law with Weibull (m = 4) Gc per edge whose mean puts the J of one tip above the Gc
    of the edge ahead of it and the J of the other below its own: one growth check cuts at the
    first tip only (each may run two edges). With one Gc below both tips' J on every edge
    (uniform), both tips cut: it is the drawn value at the edge ahead that holds the second tip."""
    spec = '{distribution="weibull", modulus=4}'
    sim = _centre_crack("fracture.toughness=1e9", f"material.random.toughness={spec}", "edge_loads.0.ramp_time=0",
                        "edge_loads.1.ramp_time=0")
    dt = 0.5 * sim.stable_dt
    sim.advance(300, dt)
    assert not sim.advances
    growth = sim.growth
    site = growth.sites.fields["toughness"][0]  # the drawn field itself, apart from the growth code
    j, ratio = [], []
    for tip in sim.tips:
        j.append(float(np.mean(sim._tip_j(tip))))
        heading, _ = sim._heading(tip, j[-1])
        ahead, _ = step_ahead(sim.shell, tip.vertex, heading)
        middle = 0.5 * (sim.shell.mesh.X[tip.vertex] + sim.shell.mesh.X[ahead])
        ratio.append(float(site(middle)[0]) / 1e9)  # the edge's Gc over the mean
    weak = int(np.argmax(np.array(j) / ratio))
    tough = 1 - weak
    mean = float(np.sqrt(j[weak] / ratio[weak] * j[tough] / ratio[tough]))
    assert j[weak] / ratio[weak] > 1.05 * j[tough] / ratio[tough], "pick another seed: the two edges draw alike"
    drawn = replace(growth, toughness=mean, sites=RandomSites.of(
        [{"toughness": RandomProperty(distribution="weibull", modulus=4.0)}], ["steel"],
        {"toughness": mean, "strength": np.inf}, 0))

    def cuts(law):
        trial = _centre_crack("fracture.toughness=1e9", f"material.random.toughness={spec}", "edge_loads.0.ramp_time=0",
                              "edge_loads.1.ramp_time=0")
        trial.advance(300, dt)
        trial.growth = law
        for tip in trial.tips:
            tip.pending = 0.011  # two edges' travel, whatever the speed
        trial._grow(dt)
        return [a.tip for a in trial.advances]

    assert drawn.edge_toughness(sim.shell.mesh, [0]).shape == (1,)
    grown = cuts(drawn)
    assert grown and set(grown) == {weak}
    uniform = cuts(replace(growth, toughness=0.99 * min(j), sites=None))
    assert set(uniform) == {0, 1}


def test_shell_region_material_draws_its_own_values():
    """A region (x < 0) with a material of its own that draws Gc (lognormal) while [material]
    does not: the edges of the region's triangles take that material's draws, those outside it
    fracture.toughness, and an edge on the region's border the lower of the two; the summary
    reports the region's material by its name."""
    sim = _centre_crack("fracture.toughness=300", 'regions=[{where={box_min=[-1.0, -1.0, -1.0], box_max=[0.0, 1.0, 1.0]}, '
                        'material={name="weak", density=7800.0, youngs_modulus=200e9, poissons_ratio=0.3, '
                        'random={toughness={distribution="lognormal", cv=0.3}}}}]')
    mesh = sim.shell.mesh
    values = sim.growth.edge_toughness(mesh, np.arange(len(mesh.edge)))
    faces = mesh.edge_face
    region = np.where(faces >= 0, mesh.region[faces], -1)
    inside, outside = np.all(region != 0, axis=1), np.all(region != 1, axis=1)
    border = ~inside & ~outside
    assert np.all(values[outside] == 300.0)
    assert np.std(values[inside]) > 0.2 * 300.0
    assert border.any() and np.all(values[border] <= 300.0)
    assert list(sim.summary()["random_properties"]) == ["weak"]


def test_shell_strength_is_drawn_per_vertex():
    """With fracture.strength drawn per vertex (lognormal), the strengths the nucleation compares
    each free-edge vertex's stress with are the drawn ones (not one value), with the requested
    mean within 3 standard errors over the boundary vertices, which the summary counts."""
    sim = _centre_crack("fracture.toughness=300", "fracture.strength=300e6",
                        'material.random.strength={distribution="lognormal", cv=0.3}')
    mesh = sim.shell.mesh
    boundary = np.unique(mesh.edge[mesh.boundary])
    values = sim.growth.vertex_strength(mesh, boundary)
    dist = RandomProperty(distribution="lognormal", cv=0.3).marginal(300e6)
    assert _within_three_standard_errors(values, dist) and np.std(values) > 0.15 * 300e6
    assert sim.summary()["random_properties"]["steel"]["strength"]["sites"] == len(boundary)


@pytest.mark.parametrize("settings, message", [
    (["material.random.toughness=" + WEIBULL], "fracture.toughness"),
    (["fracture.toughness=300", "material.random.energy=" + WEIBULL], "toughness, strength"),
])
def test_shell_bad_random_properties_are_refused(tmp_path, capsys, settings, message):
    """Gc drawn without a fracture.toughness (its mean; inf: no growth) and a property the shell
    does not draw: exit 2 naming material.random and the fix."""
    args = ["run", "shell-centre-crack", "--quick", "--out", str(tmp_path / "x")]
    for s in settings:
        args += ["--set", s]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "random" in err and message in err


# --- thread independence -----------------------------------------------------------------------


MESHFREE = ["plate-impact", "--set", "run.end_time=3e-5",
            "--set", 'material.random.tensile_strength={distribution="weibull", modulus=6, correlation_length=0.04}']
SHELL = ["shell-centre-crack", "--set", "fracture.toughness=300", "--set", "edge_loads.0.ramp_time=0", "--set",
         "edge_loads.1.ramp_time=0", "--set", "run.end_time=1e-4",
         "--set", 'material.random.toughness={distribution="weibull", modulus=4, correlation_length=0.01}']


def _run(tmp_path, threads, case):
    out = tmp_path / f"{case[0]}-t{threads}"
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads))
    subprocess.run([sys.executable, "-m", "crackle.cli", "run", *case, "--quick", "--out", str(out), "--set",
                    "run.field_frames=0"], env=env, check=True, capture_output=True)
    return out


@pytest.mark.parametrize("case, least", [(MESHFREE, 10), (SHELL, 2)], ids=["meshfree", "shell"])
def test_random_sites_identical_for_1_and_2_threads(tmp_path, case, least):
    """The quick plate impact (Weibull strengths per particle in a random field, 30 us: particles
    fail) and the quick centre crack suddenly loaded (Weibull Gc per edge in a random field,
    100 us: the tips grow): byte-identical history.csv and events.csv with 1 and 2 threads, with
    failures or cuts."""
    one, two = _run(tmp_path, 1, case), _run(tmp_path, 2, case)
    assert (one / "history.csv").read_bytes() == (two / "history.csv").read_bytes()
    events = (one / "events.csv").read_text()
    assert events == (two / "events.csv").read_text()
    assert len(events.strip().splitlines()) > least, "the compared run must fail particles or cut edges"
