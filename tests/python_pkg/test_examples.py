"""The examples of examples/python run as the README shows them."""

import subprocess
import sys
from pathlib import Path

import gmsh
from gmsh_session import gmsh_session

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples" / "python"


def test_curve_step_example_writes_a_valid_curved_mesh(tmp_path):
    step = tmp_path / "part.step"
    with gmsh_session():
        box = gmsh.model.occ.addBox(0, 0, 0, 4, 3, 2)
        hole = gmsh.model.occ.addCylinder(2, 1.5, -1, 0, 0, 4, 0.7)
        gmsh.model.occ.cut([(3, box)], [(3, hole)])
        gmsh.model.occ.synchronize()
        gmsh.write(str(step))
    run = subprocess.run([sys.executable, str(EXAMPLES / "curve_step.py"), str(step)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "valid: True" in run.stdout, run.stdout
    with gmsh_session():
        gmsh.open(str(tmp_path / "part-p3.msh"))
        types, tags, _ = gmsh.model.mesh.getElements(3)
        assert list(types) == [gmsh.model.mesh.getElementType("tetrahedron", 3)]
        assert gmsh.model.mesh.getElementQualities(tags[0], "minSJ").min() > 0


def test_plot_example_draws_the_mesh(tmp_path):
    out = tmp_path / "plate.png"
    run = subprocess.run([sys.executable, str(EXAMPLES / "plot_2d.py"), str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000


def test_the_readme_shows_the_step_example_as_it_is_tested():
    readme = (REPO / "README.md").read_text()
    block = readme.split("A STEP part curved at order 3 through gmsh", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    example = (EXAMPLES / "curve_step.py").read_text()
    code = example.split('"""', 2)[2].lstrip("\n")
    assert block == code
    assert len([line for line in code.splitlines() if line.strip() and not line.startswith("import")]) <= 10
