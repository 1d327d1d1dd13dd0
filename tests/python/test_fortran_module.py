"""The Fortran module (include/hocurve.f90) against the C header it binds
(include/hocurve.h, generated from the Rust sources): every constant with the
same value, every struct with the same fields in the same order and kinds,
every function with the same arguments, each passed the same way (by value
or by reference) with the same kind. A change to the C ABI that the module
does not follow fails here.
"""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HEADER = ROOT / "include" / "hocurve.h"
MODULE = ROOT / "include" / "hocurve.f90"

# C scalar type -> Fortran kind.
KINDS = {
    "double": "real(c_double)",
    "size_t": "integer(c_size_t)",
    "int": "integer(c_int)",
    "int32_t": "integer(c_int32_t)",
    "int64_t": "integer(c_int64_t)",
    "char": "character(kind=c_char)",
    "HocStatus": "integer(c_int)",
    "HocNodeSpacing": "integer(c_int)",
    "HocMaterial": "integer(c_int)",
    "HocFormulation": "integer(c_int)",
    "HocNodeOrdering": "integer(c_int)",
    "HocStepBackReason": "integer(c_int)",
    "HocSolvedBy": "integer(c_int)",
    "HocFallbackReason": "integer(c_int)",
}
STRUCTS = {
    "HocQuality": "hoc_quality",
    "HocOptimization": "hoc_optimization",
    "HocTimings": "hoc_timings",
    "HocRepair": "hoc_repair",
}
CALLBACKS = {"HocProjectFn", "HocProgressFn", "HocLinearSolverFn"}


def strip_c_comments(text):
    return re.sub(r"/\*.*?\*/", "", text, flags=re.S)


def c_constants(header):
    return {m[0]: m[1] for m in re.findall(r"^#define (HOC\w*) (\S+)$", header, re.M) if m[0] != "HOCURVE_H"}


def c_structs(header):
    out = {}
    for body, name in re.findall(r"typedef struct \{(.*?)\} (\w+);", strip_c_comments(header), re.S):
        fields = []
        for decl in body.split(";"):
            decl = decl.strip()
            if decl:
                ctype, field = decl.rsplit(None, 1)
                fields.append((field, KINDS[ctype]))
        out[name] = fields
    return out


def c_param(decl):
    """('name', 'value' | 'ref', kind) of one C parameter."""
    decl = decl.replace("const ", "").strip()
    m = re.match(r"(\w+)\s*(\**)\s*(\w+)$", decl)
    assert m, decl
    ctype, stars, name = m.groups()
    if ctype == "HocMesh":
        return name, ("value" if stars == "*" else "ref"), "type(c_ptr)"
    if ctype in CALLBACKS:
        return name, "value", "type(c_funptr)"
    if ctype == "void":
        return name, "value", "type(c_ptr)"
    if ctype in STRUCTS:
        return name, "ref", f"type({STRUCTS[ctype]})"
    if ctype == "char" and stars:
        return name, "value", "type(c_ptr)"  # out strings; in strings are character arrays (see below)
    return name, ("ref" if stars else "value"), KINDS[ctype]


def c_functions(header):
    out = {}
    text = strip_c_comments(header)
    for ret, name, params in re.findall(r"^([\w ]+?\**)\s*(hoc_\w+)\((.*?)\);", text, re.M | re.S):
        ps = [] if params.strip() in ("", "void") else [c_param(p) for p in params.split(",")]
        out[name] = (ret.strip(), ps, {p.split()[-1].lstrip("*"): p for p in params.split(",")})
    return out


def f_constants(module):
    return dict(re.findall(r"parameter, public :: (HOC\w*) = (\S+)", module))


def f_structs(module):
    out = {}
    for name, body in re.findall(r"type, bind\(C\), public :: (\w+)\n(.*?)end type", module, re.S):
        fields = []
        for line in body.splitlines():
            line = line.split("!")[0].strip()
            if "::" in line:
                kind, names = line.split("::")
                fields += [(n.strip(), kind.strip()) for n in names.split(",")]
        out[name] = fields
    return out


def f_functions(module):
    out = {}
    pattern = r"function (hoc_\w+)\(([^)]*)\)\s*&?\s*bind\(C, name=\"(\w+)\"\)(.*?)end function"
    for fname, args, cname, body in re.findall(pattern, re.sub(r"&\n\s*", "", module), re.S):
        decls = {}
        for line in body.splitlines():
            line = line.split("!")[0].strip()
            if "::" not in line or line.startswith("import"):
                continue
            attrs, names = line.split("::")
            attrs = [a.strip() for a in re.split(r",(?![^(]*\))", attrs)]
            for n in re.split(r",(?![^(]*\))", names):
                decls[re.sub(r"\(.*\)", "", n).strip()] = attrs
        if cname.startswith("hoc_"):  # not the C library's own (strlen for hoc_string)
            out[cname] = (fname, [a.strip() for a in args.split(",") if a.strip()], decls)
    return out


def load():
    return HEADER.read_text(), MODULE.read_text()


def assert_same_names(c, f, what):
    """The names of `c` (from the header) and `f` (from the module) agree."""
    missing = sorted(set(c) - set(f))
    assert not missing, f"{what} of hocurve.h missing from hocurve.f90: {missing}"
    extra = sorted(set(f) - set(c))
    assert not extra, f"{what} of hocurve.f90 that hocurve.h lacks: {extra}"


def test_every_constant_of_the_header_is_in_the_module_with_its_value():
    header, module = load()
    c, f = c_constants(header), f_constants(module)
    assert_same_names(c, f, "constants")
    for name, value in c.items():
        fv = f[name].replace("_c_double", "").replace("d0", "").replace("_c_int", "")
        assert float(fv) == float(value), f"{name}: {value} in C, {f[name]} in Fortran"


def test_every_struct_has_the_same_fields_in_the_same_order():
    header, module = load()
    c, f = c_structs(header), f_structs(module)
    assert set(STRUCTS) == set(c), f"structs of the header: {sorted(c)}"
    for cname, fname in STRUCTS.items():
        assert fname in f, f"no bind(C) type {fname} for {cname}"
        assert f[fname] == c[cname], f"{cname} / {fname} differ:\nC:       {c[cname]}\nFortran: {f[fname]}"


def test_every_function_has_an_interface_with_the_same_arguments():
    header, module = load()
    c, f = c_functions(header), f_functions(module)
    assert_same_names(c, f, "functions")
    for name, (ret, params, raw) in c.items():
        _, fargs, decls = f[name]
        assert len(params) == len(fargs), f"{name}: arguments {[p[0] for p in params]} in C, {fargs} in Fortran"
        # Position by position (the Fortran dummy may have its own name).
        for (pname, passing, kind), fname in zip(params, fargs):
            attrs = decls.get(fname)
            assert attrs, f"{name}: argument {fname} not declared"
            fkind = attrs[0]
            by_value = "value" in attrs
            if "char" in raw[pname] and "*" in raw[pname] and not by_value:
                # An input string: a NUL-terminated character array.
                assert fkind == "character(kind=c_char)", f"{name}({pname}): {attrs}"
                continue
            if passing == "ref" and fkind == "type(c_ptr)" and by_value:
                continue  # any pointer passed as c_loc(...) or c_null_ptr
            assert fkind == kind, f"{name}({pname}): {kind} in C, {fkind} in Fortran"
            assert by_value == (passing == "value"), f"{name}({pname}): passed by {passing} in C, {attrs} in Fortran"


def test_the_checker_sees_a_drift():
    """The checks above must fail on a module that has drifted."""
    header, module = load()
    drifted = module.replace("HOC_ERROR_PANIC = 10", "HOC_ERROR_PANIC = 12")
    assert f_constants(drifted)["HOC_ERROR_PANIC"] != c_constants(header)["HOC_ERROR_PANIC"]
    f = f_functions(module)
    name = "hoc_mesh_get_cells"
    assert len(f[name][1]) == len(c_functions(header)[name][1])
    assert len(f_functions(module.replace("ordering, len, cells) bind", "len, cells) bind"))[name][1]) == 3
