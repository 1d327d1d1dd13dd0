"""gmsh initialised for one test, quiet, and finalised after it."""

import contextlib

import gmsh


@contextlib.contextmanager
def gmsh_session():
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        yield gmsh
    finally:
        gmsh.finalize()
