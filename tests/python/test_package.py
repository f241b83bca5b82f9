"""csrbf as a Python package: csrbf/__init__.py and _interpolate.py over the compiled csrbf._core and
csrbf._io, whose type stubs (_core.pyi, _io.pyi) are checked here against the modules themselves: the
same public names, and each function's parameters as pybind11 declares them. Run by CTest as `python`."""

import ast
import inspect
import os
import re
import unittest

import csrbf
from csrbf import _core


def stub_tree(module):
    with open(os.path.splitext(module.__file__)[0].split(".")[0] + ".pyi") as f:
        return ast.parse(f.read())


def stub_names(tree):
    names = {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
    names |= {t.id for n in tree.body if isinstance(n, ast.AnnAssign) for t in [n.target] if isinstance(t, ast.Name)}
    return names


def stub_parameters(node):
    a = node.args
    return [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs if x.arg != "self"]


def pybind_parameters(function):
    """The parameter names in pybind11's signature line: 'name(a: int, b: str = ...) -> ...'."""
    line = function.__doc__.splitlines()[0]
    inner = line[line.index("(") + 1:line.rindex(") ->")]
    depth, names, current = 0, [], ""
    for ch in inner + ",":
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        if ch == "," and depth == 0:
            name = current.strip().split(":")[0].strip()
            if name and name not in ("*", "self"):
                names.append(name)
            current = ""
        else:
            current += ch
    return names


class Package(unittest.TestCase):
    def test_a_package_directory(self):
        (path,) = csrbf.__path__
        self.assertTrue(os.path.isdir(path))
        for f in ("__init__.py", "_interpolate.py", "_core.pyi", "_io.pyi", "py.typed"):
            self.assertTrue(os.path.isfile(os.path.join(path, f)), f)
        self.assertEqual(csrbf.Interpolator.__module__, "csrbf._interpolate")
        self.assertEqual(csrbf.SpaceMap.__module__, "csrbf")

    def test_stubs_name_what_the_modules_define(self):
        from csrbf import _io

        for module in (_core, _io):
            tree = stub_tree(module)
            public = {n for n in dir(module) if not n.startswith("__")} | {"__version__"} & set(dir(module))
            self.assertEqual(public - stub_names(tree), set(), module.__name__)
            self.assertEqual(stub_names(tree) - public - {"_Kernel", "_Solver", "_Path"}, set(), module.__name__)
            for node in tree.body:
                if isinstance(node, ast.FunctionDef):
                    self.assertEqual(stub_parameters(node), pybind_parameters(getattr(module, node.name)), node.name)
                if isinstance(node, ast.ClassDef):
                    cls = getattr(module, node.name)
                    for f in node.body:
                        if isinstance(f, ast.FunctionDef) and f.name in ("__init__", "__call__") and \
                                not any(isinstance(d, ast.Name) and d.id == "property" for d in f.decorator_list):
                            want = stub_parameters(f)
                            got = pybind_parameters(getattr(cls, f.name)) if cls.__doc__ is not None else want
                            self.assertEqual(want, got, f"{node.name}.{f.name}")

    def test_every_public_name_is_typed(self):
        with open(os.path.join(csrbf.__path__[0], "__init__.py")) as f:
            init = ast.parse(f.read())
        typed = set()
        for node in ast.walk(init):
            if isinstance(node, ast.ImportFrom):
                typed |= {a.asname or a.name for a in node.names}
        self.assertEqual(set(csrbf.__all__) - typed, set())
        self.assertEqual(set(csrbf.__all__), {n for n in dir(csrbf) if not n.startswith("_")})

    def test_the_interpolators_annotations_cover_its_parameters(self):
        init = inspect.signature(csrbf.Interpolator.__init__)
        for p in init.parameters.values():
            if p.name != "self":
                self.assertIsNot(p.annotation, inspect.Parameter.empty, p.name)
        self.assertTrue(re.search(r"^Interpolator\b", csrbf.Interpolator.__qualname__))


if __name__ == "__main__":
    unittest.main()
