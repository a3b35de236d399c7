"""The DEM packing generator (crackle.dem.packing): porosity, containment, overlaps, radii,
determinism (seed, numba threads), closed-surface domains, save/load, bad input.

Small packings (a few hundred to ~1500 spheres): the whole file runs in well under 30 s on 2
cores once numba's cache is warm. A cube only ~10 spheres across reaches porosity ~0.41 at best
(the walls loosen the layer along them), so the domain tests aim at 0.42 - 0.45.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numba
import numpy as np
import pytest

from crackle.dem import packing
from crackle.dem.sphere_list import read_sphere_list
from crackle.scenario import load_scenario
from crackle.dem.domains import Box, ClosedSurface, Cylinder, Sphere, from_surface
from crackle.dem.packing import Packing, pack_spheres, radius_range

RATIO = 1.86  # Rmax / Rmin of paper 003


def _pair_overlaps(centers, radii):
    """All overlaps r_a + r_b - distance > 0, by brute force (independent of the generator's grid)."""
    overlaps = []
    for s in range(len(radii) - 1):
        d = np.linalg.norm(centers[s + 1:] - centers[s], axis=1)
        o = radii[s] + radii[s + 1:] - d
        overlaps.append(o[o > 0.0])
    return np.concatenate(overlaps)


def _check_radii(p, mean_radius, ratio=RATIO):
    r_min, r_max = radius_range(mean_radius, ratio)
    r = np.sort(p.radii)
    # Ends and ratio exact to 1e-12 (relative); the radii evenly spread between them (uniform).
    assert r[0] == pytest.approx(r_min, rel=1e-12) and r[-1] == pytest.approx(r_max, rel=1e-12)
    assert r[-1] / r[0] == pytest.approx(ratio, rel=1e-12)
    np.testing.assert_allclose(r, np.linspace(r_min, r_max, len(r)), rtol=1e-12)


def _check_overlaps(p, mean_radius, tolerance=0.01):
    """Largest overlap <= 1 % of the mean radius; the reported max and mean match a brute-force
    count to 1e-12 (relative)."""
    o = _pair_overlaps(p.centers, p.radii)
    assert o.max() <= tolerance * mean_radius * (1.0 + 1e-12)
    assert p.max_overlap == pytest.approx(o.max(), rel=1e-12)
    assert p.mean_overlap == pytest.approx(o.mean(), rel=1e-12)


def _porosity(p, volume):
    return 1.0 - np.sum(4.0 / 3.0 * math.pi * p.radii**3) / volume


def test_box_porosity_containment_overlaps_radii():
    """Box 60 x 50 x 40 mm, mean radius 2.2 mm, porosity 0.42: porosity within 0.01 of the
    target, every sphere inside (x - r >= lo and x + r <= hi to 1e-12 mean radii), largest
    overlap <= 1 % of the mean radius, radii evenly spread over [Rmin, Rmax] with Rmax / Rmin =
    1.86 to 1e-12."""
    lo, hi = np.array([0.0, -0.01, 0.02]), np.array([0.06, 0.04, 0.06])
    mean_radius = 2.2e-3
    p = pack_spheres(Box(lo, hi), porosity=0.42, radius_ratio=RATIO, mean_radius=mean_radius, seed=11)
    volume = float(np.prod(hi - lo))
    assert 800 < len(p.radii) < 2000
    assert abs(_porosity(p, volume) - 0.42) <= 0.01
    assert p.porosity == pytest.approx(_porosity(p, volume), abs=1e-12)
    slack = 1e-12 * mean_radius
    assert np.all(p.centers - p.radii[:, None] >= lo - slack)
    assert np.all(p.centers + p.radii[:, None] <= hi + slack)
    _check_overlaps(p, mean_radius)
    _check_radii(p, mean_radius)
    assert p.domain == {"kind": "box", "lo": lo.tolist(), "hi": hi.tolist()}


def test_cylinder_disc_porosity_containment_overlaps_radii():
    """A tilted disc (radius 50 mm, thickness 30 mm), 1200 spheres, porosity 0.42: porosity
    within 1e-12 of the target (the count fixes the radii), every sphere inside (radial and
    axial clearance >= r - 1e-12 mean radii, computed here independently), largest overlap <= 1 %
    of the mean radius, radii as asked to 1e-12."""
    center, radius, height = np.array([0.1, 0.2, -0.05]), 0.05, 0.03
    axis = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    domain = Cylinder(center, radius, height, axis)
    p = pack_spheres(domain, porosity=0.42, count=1200, seed=5)
    mean_radius = float(np.mean(p.radii))
    assert abs(_porosity(p, math.pi * radius**2 * height) - 0.42) <= 1e-12
    q = p.centers - center
    along = q @ axis
    across = np.linalg.norm(q - along[:, None] * axis, axis=1)
    slack = 1e-12 * mean_radius
    assert np.all(across + p.radii <= radius + slack)
    assert np.all(np.abs(along) + p.radii <= 0.5 * height + slack)
    assert np.all(domain.signed_distance(p.centers) + p.radii <= slack)
    _check_overlaps(p, mean_radius)
    _check_radii(p, mean_radius)


def test_sphere_domain():
    """A ball of radius 40 mm, 600 spheres, porosity 0.45: every sphere inside (|x - c| + r <=
    R + 1e-12 mean radii), largest overlap <= 1 % of the mean radius."""
    p = pack_spheres(Sphere([0.0, 0.0, 0.0], 0.04), porosity=0.45, count=600, seed=2)
    mean_radius = float(np.mean(p.radii))
    assert np.all(np.linalg.norm(p.centers, axis=1) + p.radii <= 0.04 + 1e-12 * mean_radius)
    _check_overlaps(p, mean_radius)


def test_same_seed_same_packing_any_thread_count_other_seed_differs(monkeypatch):
    """Same seed: identical arrays (bit for bit) from the serial loops (small packings), and from
    the parallel ones with 1 and with 2 numba threads; seed + 1: different centres."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has a single thread here")
    domain = Cylinder([0.0, 0.0, 0.0], 0.03, 0.05, [1.0, 0.0, 0.0])
    serial = pack_spheres(domain, porosity=0.44, count=500, seed=3)
    again = pack_spheres(domain, porosity=0.44, count=500, seed=3)
    other = pack_spheres(domain, porosity=0.44, count=500, seed=4)
    monkeypatch.setattr(packing, "PARALLEL_MIN", 0)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = pack_spheres(domain, porosity=0.44, count=500, seed=3)
        numba.set_num_threads(2)
        two = pack_spheres(domain, porosity=0.44, count=500, seed=3)
    finally:
        numba.set_num_threads(before)
    for p in (again, one, two):
        assert p.centers.tobytes() == serial.centers.tobytes()
        assert p.radii.tobytes() == serial.radii.tobytes()
        assert (p.porosity, p.max_overlap, p.mean_overlap, p.sweeps) == (serial.porosity, serial.max_overlap,
                                                                         serial.mean_overlap, serial.sweeps)
    assert not np.array_equal(other.centers, serial.centers)


def _icosphere(radius, subdivisions):
    """Vertices and outward triangles of an icosahedron refined `subdivisions` times, its
    vertices on a sphere of `radius`."""
    g = (1.0 + 5.0**0.5) / 2.0
    vertices = [np.array(v, float) for v in [(-1, g, 0), (1, g, 0), (-1, -g, 0), (1, -g, 0), (0, -1, g), (0, 1, g),
                                             (0, -1, -g), (0, 1, -g), (g, 0, -1), (g, 0, 1), (-g, 0, -1), (-g, 0, 1)]]
    vertices = [v / np.linalg.norm(v) for v in vertices]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        middle, refined = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in middle:
                m = vertices[a] + vertices[b]
                vertices.append(m / np.linalg.norm(m))
                middle[key] = len(vertices) - 1
            return middle[key]

        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            refined += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = refined
    return radius * np.array(vertices), np.array(faces)


def _cube(lo, hi):
    v = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])], float)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return v, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def test_closed_surface_icosphere_all_inside():
    """An icosphere (320 flat triangles, radius 50 mm), 1000 spheres, porosity 0.45: every sphere
    inside the exact polyhedron (max over the face planes of the centre's distance + r <= 1e-9
    mean radii), largest overlap <= 1 % of the mean radius, and the domain's volume exact to
    1e-12."""
    vertices, triangles = _icosphere(0.05, 2)
    domain = ClosedSurface(vertices, triangles)
    normals = np.cross(vertices[triangles[:, 1]] - vertices[triangles[:, 0]],
                       vertices[triangles[:, 2]] - vertices[triangles[:, 0]])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    offsets = np.einsum("ij,ij->i", normals, vertices[triangles[:, 0]])
    # Volume: the tetrahedra from the centre to each face (the icosphere is convex around 0).
    assert domain.volume == pytest.approx(np.sum(offsets * np.linalg.norm(np.cross(
        vertices[triangles[:, 1]] - vertices[triangles[:, 0]], vertices[triangles[:, 2]] - vertices[triangles[:, 0]]),
        axis=1)) / 6.0, rel=1e-12)
    p = pack_spheres(domain, porosity=0.45, count=1000, seed=9)
    mean_radius = float(np.mean(p.radii))
    depth = (p.centers @ normals.T - offsets).max(axis=1)
    assert np.all(depth + p.radii <= 1e-9 * mean_radius)
    _check_overlaps(p, mean_radius)


def test_closed_surface_distance_of_a_cube():
    """A cube of 12 triangles on a 24-voxel grid: inside/outside by parity gives the volume exactly
    (voxel count x voxel volume = 1 to 1e-12), and inside the interpolated signed distance is
    within [0, 0.5 voxel] of the exact one (only ever shallower: the safe side)."""
    domain = ClosedSurface(*_cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]), resolution=24)
    assert np.count_nonzero(domain._grid < 0.0) * domain.voxel_size**3 == pytest.approx(1.0, rel=1e-12)
    q = np.random.default_rng(0).uniform(0.0, 1.0, (5000, 3))
    error = domain.signed_distance(q) - Box([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]).signed_distance(q)
    assert error.min() >= -1e-12 and error.max() <= 0.5 * domain.voxel_size


def test_from_surface_reads_a_file(tmp_path):
    """A 20 mm cube written as an ASCII STL in mm and read with scale 1e-3: volume 8e-6 m^3 to
    1e-12, 300 spheres all inside the cube (clearance >= r - 1e-9 mean radii)."""
    vertices, triangles = _cube([0.0, 0.0, 0.0], [20.0, 20.0, 20.0])
    lines = ["solid cube"]
    for a, b, c in triangles:
        n = np.cross(vertices[b] - vertices[a], vertices[c] - vertices[a])
        lines += [f"facet normal {n[0]} {n[1]} {n[2]}", "outer loop"]
        lines += [f"vertex {x} {y} {z}" for x, y, z in vertices[[a, b, c]]]
        lines += ["endloop", "endfacet"]
    path = tmp_path / "cube.stl"
    path.write_text("\n".join(lines + ["endsolid cube"]) + "\n")
    domain = from_surface(path, scale=1e-3, resolution=48)
    assert domain.volume == pytest.approx(8e-6, rel=1e-12)
    p = pack_spheres(domain, porosity=0.45, count=300, seed=1)
    mean_radius = float(np.mean(p.radii))
    slack = 1e-9 * mean_radius
    assert np.all(p.centers - p.radii[:, None] >= -slack) and np.all(p.centers + p.radii[:, None] <= 0.02 + slack)


def test_save_load_round_trip_exact(tmp_path):
    """save then load: every array and number identical bit for bit, the domain dict equal."""
    p = pack_spheres(Sphere([0.0, 0.0, 0.0], 0.02), porosity=0.45, count=200, seed=4)
    path = tmp_path / "packing.npz"
    p.save(path)
    q = Packing.load(path)
    assert q.centers.tobytes() == p.centers.tobytes() and q.centers.shape == p.centers.shape
    assert q.radii.tobytes() == p.radii.tobytes()
    assert q.domain == p.domain == {"kind": "sphere", "center": [0.0, 0.0, 0.0], "radius": 0.02}
    assert (q.seed, q.porosity, q.max_overlap, q.mean_overlap, q.sweeps) == (p.seed, p.porosity, p.max_overlap,
                                                                             p.mean_overlap, p.sweeps)


BOX = Box([0.0, 0.0, 0.0], [0.1, 0.1, 0.1])


@pytest.mark.parametrize(
    "arguments, field",
    [
        (dict(radius_ratio=0.9, mean_radius=0.005), "packing.radius_ratio"),
        (dict(mean_radius=-0.005), "packing.mean_radius"),
        (dict(mean_radius=0.0), "packing.mean_radius"),
        (dict(mean_radius=0.2), "packing.mean_radius"),  # larger than the box
        (dict(mean_radius=0.06), "packing.mean_radius"),  # one sphere by volume, too wide for the box
        (dict(count=0), "packing.count"),
        (dict(count=2.5), "packing.count"),
        (dict(count=1), "packing.count"),  # one sphere filling 58 % of a cube does not fit
        (dict(mean_radius=0.005, count=100), "packing.mean_radius"),
        (dict(), "packing.mean_radius"),
        (dict(porosity=0.0, count=100), "packing.porosity"),
        (dict(porosity=1.0, count=100), "packing.porosity"),
        (dict(porosity=1.5, count=100), "packing.porosity"),
        (dict(porosity=0.2, count=100), "packing.porosity"),  # denser than any random packing
        (dict(overlap_tolerance=0.0, count=100), "packing.overlap_tolerance"),
        (dict(max_sweeps=0, count=100), "packing.max_sweeps"),
    ],
)
def test_bad_input_names_the_field(arguments, field):
    """Each bad value raises ValueError whose message names its field."""
    with pytest.raises(ValueError, match=field.replace(".", r"\.")):
        pack_spheres(BOX, **arguments)


def test_bad_domains_name_the_field():
    """A box with hi <= lo, a cylinder of zero radius, an open surface: ValueError naming
    packing.domain."""
    with pytest.raises(ValueError, match=r"packing\.domain"):
        Box([0.0, 0.0, 0.0], [1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match=r"packing\.domain"):
        Cylinder([0.0, 0.0, 0.0], 0.0, 1.0)
    vertices, triangles = _cube([0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"packing\.domain"):
        ClosedSurface(vertices, triangles[:-1])


def test_unreachable_porosity_says_what_is_reachable():
    """Porosity 0.30 with 300 spheres in a cube: the spheres jam; ValueError naming
    packing.porosity with the porosity at which they do relax, between 0.36 and 0.5."""
    with pytest.raises(ValueError, match=r"packing\.porosity") as error:
        pack_spheres(BOX, porosity=0.30, count=300, seed=0)
    reachable = float(re.search(r"relax at porosity (\d\.\d+)", str(error.value)).group(1))
    assert 0.36 <= reachable <= 0.5


def test_saved_packing_replaces_an_examples_own(tmp_path):
    """`--set packing.file=...` on an example that sets mean_radius: the saved particles are the
    ones built (the same centres bit for bit), and a warning says the example's packing keys do
    not apply (nothing is silently ignored)."""
    from crackle.api import build_simulation

    packing = pack_spheres(Box([0.0, 0.0, 0.0], [0.027, 0.012, 0.054]), porosity=0.45, count=300, seed=2)
    packing.save(tmp_path / "mine.npz")
    scenario, base = load_scenario("dem-ucs", quick=True, overrides=[f"packing.file={tmp_path / 'mine.npz'}"])
    sim, _ = build_simulation(scenario, base)
    assert sim.particles.x.tobytes() == packing.centers.tobytes()
    assert any("packing.file" in w and "mean_radius" in w for w in sim.warnings)


def test_text_sphere_list_from_another_code_gives_the_same_run(tmp_path):
    """`packing.file` as a plain text sphere list (Yade's export.text: `x y z r` per line, here
    with a comment header, comma separators on some lines and an extra column): written with 17
    digits from a crackle packing, it builds the same particles bit for bit, its measured porosity
    is the packing's (1e-12), and a short quick UCS run from it gives the same history,
    byte for byte, as the run from the .npz."""
    from crackle.api import run_scenario

    made = pack_spheres(Box([0.0, 0.0, 0.0], [0.027, 0.012, 0.054]), porosity=0.45, count=300, seed=2)
    made.save(tmp_path / "mine.npz")
    lines = ["# format x_y_z_r (Yade export.text), then a clump id"]
    for k, ((x, y, z), r) in enumerate(zip(made.centers, made.radii)):
        sep = "," if k % 2 else " "
        lines.append(sep.join(f"{v:.17g}" for v in (x, y, z, r)) + f"{sep}{k % 7}")
    (tmp_path / "mine.txt").write_text("\n".join(lines) + "\n\n")
    read = read_sphere_list(tmp_path / "mine.txt", Box([0.0, 0.0, 0.0], [0.027, 0.012, 0.054]))
    assert read.centers.tobytes() == made.centers.tobytes() and read.radii.tobytes() == made.radii.tobytes()
    assert read.porosity == pytest.approx(made.porosity, abs=1e-12)
    histories = []
    for name in ("mine.npz", "mine.txt"):
        out = tmp_path / name.replace(".", "-")
        run_scenario("dem-ucs", out, quick=True, progress=False, overrides=[
            f"packing.file={tmp_path / name}", "run.end_time=5e-5", "run.field_frames=0"])
        histories.append((out / "history.csv").read_bytes())
    assert histories[0] == histories[1]


@pytest.mark.parametrize("content, expected", [
    ("0.001 0.001 0.001 0.0005\n0.002 0.002 abc 0.0005\n", "line 2: '0.002 0.002 abc 0.0005' is not 'x y z r'"),
    ("# x y z r\n0.001 0.001 0.001\n0.002 0.002 0.002 0.0005\n", "line 2: '0.001 0.001 0.001' has 3 columns"),
    ("0.001 0.001 0.001 -0.0005\n0.002 0.002 0.002 0.0005\n", "line 1: '0.001 0.001 0.001 -0.0005': the radius must be > 0"),
    ("1 1 1 0.5\n2 2 2 0.5\n", "2 of 2 sphere centres lie outside the specimen"),
    ("# nothing\n", "fewer than two spheres"),
    # a clump's members or a doubled export (crashed the step with a SystemError)
    ("0.01 0.005 0.02 0.001\n0.012 0.005 0.02 0.001\n# again\n0.01 0.005 0.02 0.001\n",
     "1 pairs of spheres share their centre, the first on lines 1 and 4 at [0.01, 0.005, 0.02] m"),
    # a 4 mm cluster in the 27 x 12 x 54 mm specimen (a UCS read 14-57x too small)
    ("0.001 0.001 0.001 0.0005\n0.002 0.002 0.002 0.0005\n", "short of its faces along z"),
    ("sphere-file.npz", "not a packing crackle saved (KeyError"),
    ("junk.npz", "not a packing crackle saved"),
])
def test_bad_sphere_list_exits_2_naming_the_line(tmp_path, capsys, content, expected):
    """A sphere list the reader cannot take: exit code 2, one line naming packing.file, the file,
    the line (or what is wrong), and no output folder. An .npz that is not crackle's (another
    code's arrays, junk bytes): the same, saying what goes in a sphere list."""
    from crackle.cli import main

    if content == "sphere-file.npz":
        np.savez(tmp_path / "spheres.npz", xyz=np.zeros((2, 3)), r=np.ones(2))
    elif content == "junk.npz":
        (tmp_path / "spheres.npz").write_bytes(bytes(range(256)) * 4)
    else:
        (tmp_path / "spheres.txt").write_text(content)
    name = "spheres.npz" if content.endswith(".npz") else "spheres.txt"
    code = main(["run", "dem-ucs", "--quick", "--set", f"packing.file={tmp_path / name}",
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2
    assert "packing.file" in err and name in err and expected in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_paper_density_packing_overlaps_and_starts_unloaded(monkeypatch):
    """packing.particle_density = 1.47 (paper 003: spheres per cubed mean diameter) in the quick
    UCS prism with mean radius 0.75 mm: n (2 mean R)^3 / V within 2 % of 1.47 (7,620 spheres,
    the parallel path), every sphere inside, a solid fraction (spheres' volume / V, overlaps
    counted twice) of the paper's ~0.84 within 0.02 (measured 0.839), mean overlap 0.14 R
    (measured), the same bits with 1 and 2 numba threads; the DEM sample built on it holds 12 bonds
    per particle within 0.5 % and carries no force at step 0 (the bonds rest at the packed
    distances)."""
    from crackle.api import build_simulation
    from crackle.scenario import load_scenario

    domain = Box([0.0, 0.0, 0.0], [0.027, 0.012, 0.054])
    packs = []
    before = numba.get_num_threads()
    for threads in (1, 2):
        numba.set_num_threads(threads)
        packs.append(pack_spheres(domain, mean_radius=7.5e-4, particle_density=1.47, seed=1))
    numba.set_num_threads(before)
    p = packs[0]
    assert p.centers.tobytes() == packs[1].centers.tobytes() and p.radii.tobytes() == packs[1].radii.tobytes()
    n, mean_d = len(p.radii), 2.0 * float(p.radii.mean())
    print(f"{n} spheres, n d^3 / V = {n * mean_d**3 / domain.volume:.4f}, solid fraction {1 - p.porosity:.3f}, "
          f"mean overlap {p.mean_overlap / (mean_d / 2):.3f} R, largest {p.max_overlap / (mean_d / 2):.3f} R")
    assert n * mean_d**3 / domain.volume == pytest.approx(1.47, rel=0.02)
    assert np.all(domain.signed_distance(p.centers) + p.radii <= 1e-12 * mean_d)
    assert 1.0 - p.porosity == pytest.approx(0.84, abs=0.02)
    assert p.mean_overlap > 0.05 * mean_d / 2

    scenario, base = load_scenario("dem-ucs", quick=True, overrides=["packing.mean_radius=7.5e-4"])
    sim, _ = build_simulation(scenario, base)
    assert sim.particles.x.tobytes() == p.centers.tobytes()
    assert sim.n_bonds / n * 2 == pytest.approx(12.0, rel=0.005)
    sim.advance(1, 1e-12)
    assert np.max(np.abs(sim.inter.transfer[:, :3])) == 0.0


def _compacted_between_walls(tmp_path, poke: float) -> Path:
    """A text sphere list like one compacted between six walls by another code: crackle's packing
    of the dem-ucs quick box (paper 003's density) stretched about the box's centre so that the
    spheres flush with a face poke `poke` (m) through it, as walls at the compaction stress leave
    them; written `x y z r` with a comment and an id column."""
    lo, hi = np.zeros(3), np.array([0.027, 0.012, 0.054])
    made = pack_spheres(Box(lo, hi), particle_density=1.47, mean_radius=1e-3, seed=1)
    middle = 0.5 * (lo + hi)
    centers = middle + (made.centers - middle) * (1.0 + 2.0 * poke / (hi - lo - 2.0 * made.radii.mean()))
    lines = ["# x y z r id (compacted between walls; spheres at the faces overlap them)"]
    lines += [" ".join(f"{v:.17g}" for v in (*c, r)) + f" {k}" for k, (c, r) in enumerate(zip(centers, made.radii))]
    path = tmp_path / "walls.txt"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.slow
def test_seated_platens_start_unloaded_on_a_packing_that_overlaps_them(tmp_path):
    """Issue 43: platens on the box faces of a packing whose spheres poke through them (0.1 mm,
    a tenth of the mean radius). Unseated, they push those spheres at once (the platen stress
    after one step is over 1 GPa, and a warning says so); seated (the examples' `seat = true`),
    the platen force after the first step is exactly zero, and in the quick UCS run the first bond
    breaks only at a sizable part of the peak: at least 15 % (measured 16.7 MPa = 27 % of
    61.6 MPa, 2026-12-06; 26 % of 63.2 MPa before; crackle's own packing, flush with the faces:
    16.9 MPa = 26 % of 65.5 MPa). The run stops once the force has stayed below 80 % of its peak
    for 10 us (the example's rule: 50 % for 0.1 ms), past the peak (the force falls to 80 % of it
    in 80 us and never dipped 0.5 % below its running peak before it: measured), which is the
    same to the bit, in 14 % fewer steps; no plots/."""
    from crackle.api import build_simulation, run_scenario

    path = _compacted_between_walls(tmp_path, 1e-4)
    for seat in ("false", "true"):
        scenario, base = load_scenario("dem-ucs", quick=True, overrides=[
            f"packing.file={path}", f"tools.0.seat={seat}", f"tools.1.seat={seat}"])
        sim, control = build_simulation(scenario, base)
        inside = [w for w in sim.warnings if "inside it" in w]
        assert len(inside) == 2 and all(("seat = true)" in w) == (seat == "true") for w in inside), inside
        sim.advance(1, 0.7 * sim.stable_dt)
        row = sim.sample(0.7 * sim.stable_dt)
        if seat == "false":
            assert row["platen.stress"] > 1e9
        else:
            assert row["tool.top.fz"] == 0.0 and row["tool.bottom.fz"] == 0.0 and row["platen.stress"] == 0.0
    out = tmp_path / "seated"
    result = run_scenario("dem-ucs", out, quick=True, progress=False, plots=False, overrides=[
        f"packing.file={path}", "run.field_frames=0", "run.stop.force_drop=0.8", "run.stop.force_drop_hold=1e-5"])
    history = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    events = np.genfromtxt(out / "events.csv", delimiter=",", names=True)
    first = float(np.interp(np.min(events["time"]), history["time"], history["platenstress"]))
    peak = result.summary["peak_stress"]
    print(f"first break at {first * 1e-6:.1f} MPa, peak {peak * 1e-6:.1f} MPa ({first / peak:.2f})")
    assert first > 0.15 * peak and peak > 30e6


def test_a_particle_density_whose_spheres_outgrow_the_box_is_refused():
    """Issue 71 item 8: packing.particle_density = 5 (1.47 meant) would grow spheres whose volumes
    add to 2.85x the box (mean radius 1 mm, Rmax / Rmin = 1.86): refused before any packing, with
    the largest density that fits (1.75: the spheres' volumes the box's), and 1.7 packs."""
    box = Box(np.zeros(3), np.array([0.027, 0.012, 0.054]))
    with pytest.raises(ValueError, match=r"particle_density = 5: the spheres' volumes would add to 2.85x the "
                                         r"domain's.*at most 1.75"):
        pack_spheres(box, particle_density=5.0, mean_radius=1e-3, seed=1, max_sweeps=1)
    made = pack_spheres(box, particle_density=1.7, mean_radius=1e-3, seed=1)
    assert len(made.radii) == round(1.7 * box.volume / 2e-3 ** 3)
