"""Tests for crackle.geometry: mesh generation, import, checks, selections, faces."""

import warnings

import meshio
import numpy as np
import pytest

from crackle.geometry import (
    LOCAL_FACE_VERTICES,
    MeshError,
    TetMesh,
    check_tets,
    disc,
    gmsh_box,
    gmsh_cylinder,
    gmsh_from_surface,
    internal_faces,
    nodes_in_box,
    nodes_on_plane,
    read_mesh,
    structured_box,
)


def boundary_triangles(mesh: TetMesh) -> np.ndarray:
    """Outward-oriented boundary triangles of a tet mesh."""
    b = internal_faces(mesh.tets).boundary_faces
    return mesh.tets[b[:, [0]], LOCAL_FACE_VERTICES[b[:, 1]]]


# --------------------------------------------------------------------------- #
# structured_box
# --------------------------------------------------------------------------- #
@pytest.mark.parametrize(
    "size, h, expected_tets",
    [
        ((0.06, 0.12, 0.02), 0.02, 432),  # 3 x 6 x 1 cells x 24
        ((0.5, 0.05, 0.02), 0.025, 960),  # 20 x 2 x 1 (0.8 rounds to 1)
        ((0.5, 0.05, 0.02), 0.01, 12000),  # 50 x 5 x 2
        ((0.06, 0.12, 0.02), 0.01, 3456),  # 6 x 12 x 2
    ],
)
def test_structured_box_tet_counts(size, h, expected_tets):
    """Exact tet counts: 432, 960, 12000, 3456."""
    mesh = structured_box(size, h)
    assert mesh.n_tets == expected_tets


@pytest.mark.parametrize("size, h", [((0.06, 0.12, 0.02), 0.01), ((0.5, 0.05, 0.02), 0.025)])
def test_structured_box_volume_positive_and_exact(size, h):
    """Sum of tet volumes equals Lx*Ly*Lz to 1e-12 relative; every volume > 0."""
    mesh = structured_box(size, h, origin=(1.0, -2.0, 0.5))
    vol = mesh.volumes()
    assert np.all(vol > 0)
    assert abs(vol.sum() / np.prod(size) - 1.0) < 1e-12
    lo, hi = mesh.bounds()
    np.testing.assert_allclose(lo, [1.0, -2.0, 0.5])
    np.testing.assert_allclose(hi, np.add([1.0, -2.0, 0.5], size))
    check_tets(mesh, source="structured_box")


def test_structured_box_nodes_shared():
    """3x6x1 cells: 4*7*2 = 56 corners + 81 face centres + 18 cell centres = 155 nodes, no duplicates."""
    mesh = structured_box((0.06, 0.12, 0.02), 0.02)
    # face centres: x-faces 4*6*1 + y-faces 3*7*1 + z-faces 3*6*2 = 24 + 21 + 36 = 81
    assert mesh.n_points == 56 + 81 + 18
    rounded = np.round(mesh.points / 1e-9).astype(np.int64)
    assert np.unique(rounded, axis=0).shape[0] == mesh.n_points
    # Conforming: the only boundary is the outer box surface, area 2*(ab+bc+ca).
    tri = boundary_triangles(mesh)
    p = mesh.points
    cross = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    area = 0.5 * np.linalg.norm(cross, axis=1).sum()
    assert area == pytest.approx(2 * (0.06 * 0.12 + 0.12 * 0.02 + 0.02 * 0.06), rel=1e-12)


def test_structured_box_element_size_single_cell():
    """Unit cell: 50 unique edges, mean = (12*1 + 24*sqrt(2)/2 + 8*sqrt(3)/2 + 6*0.5) / 50."""
    mesh = structured_box((1.0, 1.0, 1.0), 1.0)
    assert mesh.edges().shape[0] == 50
    expected = (12 + 24 * np.sqrt(2) / 2 + 8 * np.sqrt(3) / 2 + 6 * 0.5) / 50
    assert mesh.element_size() == pytest.approx(expected, rel=1e-12)


def test_structured_box_bad_input():
    """Non-positive element size -> MeshError."""
    with pytest.raises(MeshError):
        structured_box((1.0, 1.0, 1.0), 0.0)


# --------------------------------------------------------------------------- #
# internal_faces
# --------------------------------------------------------------------------- #
def test_internal_faces_single_cell():
    """One cell of 24 tets: 36 internal faces, 24 boundary faces (each tet has 3 internal + 1 boundary)."""
    mesh = structured_box((1.0, 1.0, 1.0), 1.0)
    faces = internal_faces(mesh.tets)
    assert mesh.n_tets == 24
    assert faces.face_tet.shape == (36, 2)
    assert faces.face_local.shape == (36, 2)
    assert faces.boundary_faces.shape == (24, 2)
    # every tet: 3 internal faces and 1 boundary face
    assert np.array_equal(np.bincount(faces.face_tet.ravel(), minlength=24), np.full(24, 3))
    assert np.array_equal(np.bincount(faces.boundary_faces[:, 0], minlength=24), np.ones(24))


def test_internal_faces_match_nodes_and_normals():
    """3456-tet box: 4*m = 2*internal + boundary; paired faces share 3 nodes; boundary normals point out."""
    mesh = structured_box((0.06, 0.12, 0.02), 0.01)
    faces = internal_faces(mesh.tets)
    assert 4 * mesh.n_tets == 2 * len(faces.face_tet) + len(faces.boundary_faces)
    assert np.all(faces.face_tet[:, 0] < faces.face_tet[:, 1])
    nodes_a = np.sort(mesh.tets[faces.face_tet[:, [0]], LOCAL_FACE_VERTICES[faces.face_local[:, 0]]], axis=1)
    nodes_b = np.sort(mesh.tets[faces.face_tet[:, [1]], LOCAL_FACE_VERTICES[faces.face_local[:, 1]]], axis=1)
    assert np.array_equal(nodes_a, nodes_b)
    # local face f is opposite vertex f
    opposite = mesh.tets[faces.face_tet[:, 0], faces.face_local[:, 0]]
    assert not np.any(nodes_a == opposite[:, None])
    # boundary face normals (LOCAL_FACE_VERTICES order) point away from the tet centroid
    p = mesh.points
    tri = boundary_triangles(mesh)
    normal = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    centroid = p[mesh.tets[faces.boundary_faces[:, 0]]].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", normal, p[tri].mean(axis=1) - centroid) > 0)


def test_internal_faces_non_manifold():
    """A face shared by 3 tets -> MeshError 'non-manifold'."""
    tets = np.array([[0, 1, 2, 3], [0, 2, 1, 4], [0, 1, 2, 5]])
    with pytest.raises(MeshError, match="non-manifold"):
        internal_faces(tets)


# --------------------------------------------------------------------------- #
# gmsh meshing
# --------------------------------------------------------------------------- #
def test_gmsh_box_volume_and_determinism():
    """gmsh box 0.06x0.12x0.02 at h=5 mm: volume exact to 1e-12, volumes > 0, two calls identical."""
    size = (0.06, 0.12, 0.02)
    mesh = gmsh_box(size, 0.005, origin=(0.1, 0.0, -0.01))
    vol = mesh.volumes()
    assert np.all(vol > 0)
    assert abs(vol.sum() / np.prod(size) - 1.0) < 1e-12
    np.testing.assert_allclose(mesh.bounds()[0], [0.1, 0.0, -0.01], atol=1e-15)
    # no unused nodes
    assert np.unique(mesh.tets).size == mesh.n_points
    again = gmsh_box(size, 0.005, origin=(0.1, 0.0, -0.01))
    assert np.array_equal(mesh.tets, again.tets)
    assert np.array_equal(mesh.points, again.points)


def test_disc_paper_size():
    """Disc D=40 mm, t=15 mm, h=1.2 mm: 40k-60k tets (paper: 51,690), volume pi*r^2*t within 1%."""
    mesh = disc(0.04, 0.015, 0.0012)
    assert 40_000 <= mesh.n_tets <= 60_000
    vol = mesh.volumes()
    assert np.all(vol > 0)
    assert abs(vol.sum() / (np.pi * 0.02**2 * 0.015) - 1.0) < 0.01
    lo, hi = mesh.bounds()
    np.testing.assert_allclose(lo, [-0.02, -0.02, -0.0075], atol=1e-5)
    np.testing.assert_allclose(hi, [0.02, 0.02, 0.0075], atol=1e-5)


def test_gmsh_cylinder_tilted_axis():
    """Cylinder r=10 mm, L=30 mm along (1,1,0) at (1,2,3): volume within 1%, centroid at the centre."""
    mesh = gmsh_cylinder(0.01, 0.03, 0.002, center=(1.0, 2.0, 3.0), axis=(1.0, 1.0, 0.0))
    vol = mesh.volumes()
    assert np.all(vol > 0)
    assert abs(vol.sum() / (np.pi * 0.01**2 * 0.03) - 1.0) < 0.01
    centroid = (mesh.points[mesh.tets].mean(axis=1) * vol[:, None]).sum(axis=0) / vol.sum()
    np.testing.assert_allclose(centroid, [1.0, 2.0, 3.0], atol=1e-4)


@pytest.mark.parametrize("suffix", [".stl", ".vtk"])
@pytest.mark.parametrize("remesh", [True, False])
def test_gmsh_from_surface_box(tmp_path, suffix, remesh):
    """Closed box surface 20x30x10 mm (STL or VTK triangles): enclosed volume 6e-6 m^3 to 1e-12."""
    box = structured_box((0.02, 0.03, 0.01), 0.01)
    path = tmp_path / f"box{suffix}"
    meshio.write(path, meshio.Mesh(box.points, [("triangle", boundary_triangles(box))]))
    mesh = gmsh_from_surface(path, 0.004, remesh_surface=remesh)
    vol = mesh.volumes()
    assert np.all(vol > 0)
    assert abs(vol.sum() / 6e-6 - 1.0) < 1e-12


@pytest.mark.parametrize("remesh", [True, False])
def test_gmsh_from_surface_open_surface(tmp_path, remesh):
    """Box surface with 2 of its 24 triangles removed (not closed) -> MeshError naming the file."""
    box = structured_box((0.02, 0.03, 0.01), 0.01)
    path = tmp_path / "open.stl"
    meshio.write(path, meshio.Mesh(box.points, [("triangle", boundary_triangles(box)[2:])]))
    with pytest.raises(MeshError, match="open.stl"):
        gmsh_from_surface(path, 0.004, remesh_surface=remesh)


def test_gmsh_leaves_user_session_alone():
    """Caller-owned gmsh session: still initialised after, current model and MeshSizeMax (0.123) restored."""
    import gmsh

    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("user_model")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.123)
        mesh = gmsh_box((0.01, 0.01, 0.01), 0.005)
        assert mesh.n_tets > 0
        assert gmsh.isInitialized()
        assert gmsh.model.getCurrent() == "user_model"
        assert gmsh.option.getNumber("Mesh.MeshSizeMax") == 0.123
    finally:
        gmsh.finalize()


def test_gmsh_from_surface_missing_file(tmp_path):
    """Missing surface file -> MeshError 'does not exist'."""
    with pytest.raises(MeshError, match="does not exist"):
        gmsh_from_surface(tmp_path / "nope.stl", 0.01)


# --------------------------------------------------------------------------- #
# read_mesh and check_tets
# --------------------------------------------------------------------------- #
@pytest.mark.parametrize("suffix", [".vtu", ".vtk", ".msh", ".inp"])
def test_read_mesh_round_trip(tmp_path, suffix):
    """Write a 432-tet box with meshio, read it back: same 432 tets, same points, 1 unused point dropped."""
    mesh = structured_box((0.06, 0.12, 0.02), 0.02)
    # an extra, unused point that read_mesh must drop
    points = np.vstack([mesh.points, [[9.0, 9.0, 9.0]]])
    path = tmp_path / f"box{suffix}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # meshio warns about missing gmsh physical tags
        meshio.write(path, meshio.Mesh(points, [("tetra", mesh.tets)]))
    back = read_mesh(path)
    assert back.n_tets == 432
    assert back.n_points == mesh.n_points
    np.testing.assert_allclose(back.points, mesh.points, rtol=0, atol=1e-12)
    assert np.array_equal(back.tets, mesh.tets)


def test_read_mesh_inverted(tmp_path):
    """Two inverted tets in a file -> MeshError mentioning 'inverted', the count 2 and the first, index 5,
    as tet 6 (counted from 1)."""
    mesh = structured_box((0.06, 0.12, 0.02), 0.02)
    tets = mesh.tets.copy()
    tets[[5, 7]] = tets[[5, 7]][:, [0, 2, 1, 3]]
    path = tmp_path / "inverted.vtu"
    meshio.write(path, meshio.Mesh(mesh.points, [("tetra", tets)]))
    with pytest.raises(MeshError, match="inverted") as err:
        read_mesh(path)
    msg = str(err.value)
    assert "inverted.vtu" in msg and "2 inverted" in msg and "first is tet 6 " in msg


def test_check_tets_degenerate():
    """A flat tet (4 coplanar nodes) -> MeshError 'degenerate'."""
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    with pytest.raises(MeshError, match="degenerate"):
        check_tets(TetMesh(points, [[0, 1, 2, 3]]), source="flat")


def test_read_mesh_missing_file(tmp_path):
    """Missing mesh file -> MeshError 'does not exist' naming the file."""
    with pytest.raises(MeshError, match="does not exist") as err:
        read_mesh(tmp_path / "missing.msh")
    assert "missing.msh" in str(err.value)


def test_read_mesh_only_triangles(tmp_path):
    """File with only triangles -> MeshError 'no 4-node tetrahedra' listing 'triangle'."""
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    path = tmp_path / "tri.vtu"
    meshio.write(path, meshio.Mesh(points, [("triangle", np.array([[0, 1, 2]]))]))
    with pytest.raises(MeshError, match="no 4-node tetrahedra") as err:
        read_mesh(path)
    assert "triangle" in str(err.value) and "tri.vtu" in str(err.value)


def test_read_mesh_unreadable(tmp_path):
    """Garbage content -> MeshError naming the file and 'meshio cannot read'."""
    path = tmp_path / "garbage.vtu"
    path.write_text("this is not a mesh")
    with pytest.raises(MeshError, match="meshio cannot read") as err:
        read_mesh(path)
    assert "garbage.vtu" in str(err.value)


# --------------------------------------------------------------------------- #
# Selections
# --------------------------------------------------------------------------- #
def test_selections():
    """3x6x1-cell box (155 nodes): 20 nodes on plane x=0, 46 nodes on the bottom face z=0."""
    mesh = structured_box((0.06, 0.12, 0.02), 0.02)
    p = mesh.points
    # plane x = 0: corners 7*2 = 14 + x-face centres 6*1 = 6 -> 20 nodes
    on_x0 = nodes_on_plane(p, point=(0, 0, 0), normal=(2.0, 0, 0), tol=1e-9)
    assert on_x0.sum() == 20
    # tilted plane: same answer for any normal scaling
    assert np.array_equal(on_x0, nodes_on_plane(p, (0, 0.05, 0.01), (-1, 0, 0), 1e-9))
    # box selecting the bottom face z=0: corners 4*7 + z-face centres 3*6 = 46
    bottom = nodes_in_box(p, lo=(-1, -1, -1e-9), hi=(1, 1, 1e-9))
    assert bottom.sum() == 46
    assert np.array_equal(bottom, nodes_on_plane(p, (0, 0, 0), (0, 0, 1), 1e-9))
    # whole bounds (inclusive) -> all 155 nodes
    assert nodes_in_box(p, *mesh.bounds()).sum() == mesh.n_points == 155


def test_locality_order_keeps_the_mesh_and_groups_neighbours():
    """locality_order renumbers, nothing else: the same tets (as point sets), volumes and
    orientation; and neighbouring tets end up close in memory (mean index distance between tets
    sharing a face drops well below gmsh's own order on a disc)."""
    from crackle.geometry.meshes import locality_order

    mesh = gmsh_cylinder(0.02, 0.015, 0.003)
    ordered, order = locality_order(mesh)
    assert sorted(order.tolist()) == list(range(mesh.n_tets))
    np.testing.assert_array_equal(ordered.points[ordered.tets], mesh.points[mesh.tets][order])
    assert np.all(ordered.volumes() > 0)

    def spread(m):
        pairs = internal_faces(m.tets).face_tet
        return float(np.mean(np.abs(pairs[:, 0] - pairs[:, 1])))

    assert spread(ordered) < 0.5 * spread(mesh)


def test_abaqus_labels_reach_the_summary(tmp_path):
    """Tets read from an Abaqus file keep the file's element labels (1001, 1002 here) for the
    user: the time-step report in summary.json names the critical tet by its label, not by
    crackle's count (1 or 2)."""
    from crackle.fdem.model import build_fdem_model
    from fdem_helpers import rock

    inp = tmp_path / "two.inp"
    inp.write_text(
        "*NODE\n1, 0, 0, 0\n2, 0.01, 0, 0\n3, 0, 0.01, 0\n4, 0, 0, 0.01\n5, 0.01, 0.01, 0.01\n"
        "*ELEMENT, TYPE=C3D4, ELSET=rock\n1001, 1, 2, 3, 4\n1002, 2, 5, 3, 4\n"
    )
    mesh = read_mesh(inp)
    assert [mesh.label(i) for i in range(mesh.n_tets)] == [1001, 1002]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the coarse-mesh advice: two 10 mm tets
        model = build_fdem_model(mesh, rock())
    assert model.time_step.as_summary(mesh.label)["element"] == 1000 + model.time_step.element


def test_a_mesh_file_is_ordered_for_the_cache_and_keeps_the_files_numbers(tmp_path):
    """A specimen read from a file (a gmsh disc written in a shuffled order) is stepped in the
    locality order crackle gives its own meshes (the file's order stepped 1.8-2.1x slower), and
    every tet keeps its number in the file: label - 1 is its row there (the same four points).
    Groups of tets and named surfaces follow the renumbering (the same tets and triangles in space)."""
    import types

    from crackle.geometry.meshes import locality_order
    from crackle.geometry.specimens import specimen_mesh

    disc = gmsh_cylinder(0.02, 0.015, 0.004)
    shuffled = np.random.default_rng(7).permutation(disc.n_tets)
    path = tmp_path / "disc.vtu"
    meshio.write(path, meshio.Mesh(disc.points, [("tetra", disc.tets[shuffled])]))
    file_mesh = read_mesh(path)

    mesh, _ = specimen_mesh(types.SimpleNamespace(shape="mesh", file=str(path), scale=1.0), None)
    expected, _ = locality_order(file_mesh)
    np.testing.assert_array_equal(mesh.points[mesh.tets], expected.points[expected.tets])
    np.testing.assert_array_equal(mesh.points[mesh.tets], file_mesh.points[file_mesh.tets[mesh.labels - 1]])
    assert sorted(mesh.labels.tolist()) == list(range(1, disc.n_tets + 1))
    assert not np.array_equal(mesh.labels, np.arange(1, disc.n_tets + 1))  # reordered, numbered as in the file
    assert mesh.label(0) == int(mesh.labels[0])

    centroids = file_mesh.points[file_mesh.tets].mean(axis=1)
    left = np.flatnonzero(centroids[:, 0] < 0.0)
    ends = np.flatnonzero(np.isclose(file_mesh.points[:, 2], 0.0))[:3][None, :]
    grouped = TetMesh(file_mesh.points, file_mesh.tets, groups={"left": left}, surfaces={"end": ends})
    ordered, _ = locality_order(grouped)
    again = ordered.points[ordered.tets].mean(axis=1)[ordered.groups["left"]]
    assert np.array_equal(np.sort(again, axis=0), np.sort(centroids[left], axis=0))
    np.testing.assert_array_equal(ordered.points[ordered.surfaces["end"]], file_mesh.points[ends])
