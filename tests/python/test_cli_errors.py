"""Bad input: non-zero exit, one clear `hocurve: error:` line, no output left behind."""
import json

import pytest

import meshes as M


@pytest.fixture
def plate(gmsh, tmp_path):
    """A linear 2D mesh and the --geometry argument for its hole."""
    tags = M.square_with_hole(gmsh, 0.5)
    path = tmp_path / "plate.msh"
    M.write_msh41(gmsh, path)
    return path, None, tags


def curve_args(src, out, *extra, order="2", geometry=None):
    args = ["curve", src, "--order", order]
    for g in geometry or []:
        args += ["--geometry", g]
    return args + ["--output", out, *extra]


def assert_fails(hocurve, tmp_path, args, message):
    before = set(tmp_path.iterdir())
    r = hocurve.run(*args)
    assert r.returncode != 0, f"exit 0 for {args}\n{r.stderr}"
    err = [l for l in r.stderr.splitlines() if l.startswith("hocurve: error:")]
    assert len(err) == 1, r.stderr
    assert message.lower() in err[0].lower(), err[0]
    assert set(tmp_path.iterdir()) == before, "files left behind"
    return err[0]


def hole(tags):
    return [f"{t}=circle:0,0,{M.RADIUS}" for t in tags]


def test_missing_file(hocurve, tmp_path):
    assert_fails(hocurve, tmp_path, curve_args(tmp_path / "nope.msh", tmp_path / "o.msh", geometry=["1=circle:0,0,1"]),
                 "nope.msh")


@pytest.mark.parametrize("cut", [0.1, 0.5, 0.9])
def test_malformed_msh(hocurve, plate, tmp_path, cut):
    src, _g, tags = plate
    data = src.read_bytes()
    bad = tmp_path / "bad.msh"
    bad.write_bytes(data[: int(len(data) * cut)])
    out = tmp_path / "o.msh"
    assert_fails(hocurve, tmp_path, curve_args(bad, out, geometry=hole(tags)), "bad.msh")


def test_not_an_msh(hocurve, tmp_path):
    bad = tmp_path / "bad.msh"
    bad.write_text("this is not a mesh\n")
    assert_fails(hocurve, tmp_path, ["quality", bad], "bad.msh")


@pytest.mark.parametrize("shape,msg", [("blob:1,2", "unknown kind"), ("circle:0,0", "circle"),
                                        ("sphere:0,0,0,x", "sphere"), ("", "")])
def test_bad_shape(hocurve, plate, tmp_path, shape, msg):
    src, _g, tags = plate
    assert_fails(hocurve, tmp_path, curve_args(src, tmp_path / "o.msh", geometry=[f"{tags[0]}={shape}"]), msg)


def test_bad_geometry_syntax(hocurve, plate, tmp_path):
    src, _g, _t = plate
    assert_fails(hocurve, tmp_path, curve_args(src, tmp_path / "o.msh", geometry=["circle:0,0,1"]), "TAG=SHAPE")
    assert_fails(hocurve, tmp_path, curve_args(src, tmp_path / "o.msh", geometry=["x=circle:0,0,1"]), "integer tag")


@pytest.mark.parametrize("order", ["11", "0", "two"])
def test_bad_order(hocurve, plate, tmp_path, order):
    src, _g, tags = plate
    assert_fails(hocurve, tmp_path, curve_args(src, tmp_path / "o.msh", order=order, geometry=hole(tags)), "order")


@pytest.mark.parametrize("nu", ["0.5", "0.7", "-1.5", "abc"])
def test_bad_poisson(hocurve, plate, tmp_path, nu):
    src, _g, tags = plate
    assert_fails(hocurve, tmp_path, curve_args(src, tmp_path / "o.msh", "--poisson", nu, geometry=hole(tags)),
                 "poisson")


@pytest.mark.parametrize("flag,value,msg", [("--formulation", "foo", "formulation"),
                                             ("--material", "rubber", "material"),
                                             ("--spacing", "random", "spacing"),
                                             ("--increments", "-3", "increments"),
                                             ("--bogus", "1", "unknown option")])
def test_bad_option(hocurve, plate, tmp_path, flag, value, msg):
    src, _g, tags = plate
    assert_fails(hocurve, tmp_path, curve_args(src, tmp_path / "o.msh", flag, value, geometry=hole(tags)), msg)


def test_bad_output(hocurve, plate, tmp_path):
    src, _g, tags = plate
    assert_fails(hocurve, tmp_path, curve_args(src, tmp_path / "o.txt", geometry=hole(tags)), ".msh or .vtu")
    assert_fails(hocurve, tmp_path, curve_args(src, tmp_path / "no" / "dir" / "o.msh", geometry=hole(tags)),
                 "cannot write")


def test_missing_arguments(hocurve, plate, tmp_path):
    src, _g, tags = plate
    assert_fails(hocurve, tmp_path, ["curve", src, "--output", tmp_path / "o.msh"], "--order")
    assert_fails(hocurve, tmp_path, ["curve", src, "--order", "2"], "--output")
    assert_fails(hocurve, tmp_path, ["frobnicate"], "unknown command")


def test_tag_without_facets_is_an_error(hocurve, plate, tmp_path):
    """A --geometry tag that matches no facet is a typo: refuse it, write nothing."""
    src, _g, _t = plate
    assert_fails(hocurve, tmp_path, curve_args(src, tmp_path / "o.msh", geometry=["999=circle:0,0,0.5"]),
                 "entity tag 999")


def test_unwritable_report_fails_before_writing_the_mesh(hocurve, plate, tmp_path):
    src, _g, tags = plate
    args = curve_args(src, tmp_path / "o.msh", geometry=hole(tags)) + ["--report", tmp_path / "nodir" / "r.json"]
    assert_fails(hocurve, tmp_path, args, "cannot write")


def test_every_option_the_usage_lists_is_accepted(hocurve, plate, tmp_path):
    """`hocurve curve` accepts the Newton settings its usage text shows."""
    src, _g, tags = plate
    out = tmp_path / "o.msh"
    r = hocurve.run(*curve_args(src, out, "--tolerance", "1e-8", "--max-iterations", "30", geometry=hole(tags)))
    assert r.returncode == 0, r.stderr
    assert out.exists()
