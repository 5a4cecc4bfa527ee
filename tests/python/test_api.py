"""The public API as the stubs declare it: every name there exists at run time with the same docstring that
help() shows, no private name is declared, and everything public at run time is declared."""
import ast
import os
import pydoc

import pytest

import stylerf

STUBS = os.path.join(os.path.dirname(stylerf.__file__), "__init__.pyi")


def words(text):
    """A docstring with its line breaks and indentation folded: the stubs and the bindings wrap differently."""
    return " ".join((text or "").split())


def is_dunder(name):
    return name.startswith("__") and name.endswith("__")


class Stubs:
    """What __init__.pyi declares: top-level functions and classes with their docstrings, each class's
    members, the names re-exported from api_types, and the aliases and variables."""

    def __init__(self, path):
        with open(path) as f:
            self.tree = ast.parse(f.read())
        self.functions, self.classes, self.reexports, self.variables = {}, {}, [], []
        for node in self.tree.body:
            if isinstance(node, ast.FunctionDef):
                self.functions[node.name] = ast.get_docstring(node)
            elif isinstance(node, ast.ClassDef):
                members = {n.name: ast.get_docstring(n) for n in node.body if isinstance(n, ast.FunctionDef)}
                self.classes[node.name] = (ast.get_docstring(node), members)
            elif isinstance(node, ast.ImportFrom) and node.module == "api_types":
                self.reexports += [a.asname or a.name for a in node.names]
            elif isinstance(node, ast.AnnAssign):
                self.variables.append(node.target.id)
            elif isinstance(node, ast.Assign):
                self.variables += [t.id for t in node.targets]

    def every_name(self):
        """Every name the stubs declare, at any depth (defined, re-exported or a parameter's)."""
        for node in ast.walk(self.tree):
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                yield node.name
                if isinstance(node, ast.FunctionDef):
                    args = node.args
                    for a in args.posonlyargs + args.args + args.kwonlyargs:
                        yield a.arg
            elif isinstance(node, ast.alias):
                yield node.asname or node.name
            elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                yield node.id

    def public_names(self):
        return set(self.functions) | set(self.classes) | set(self.reexports) | set(self.variables)


@pytest.fixture(scope="module")
def stubs():
    return Stubs(STUBS)


def runtime_member(cls, name):
    """The class attribute itself: a property object for a property, not its value on an instance."""
    for klass in cls.__mro__:
        if name in vars(klass):
            return vars(klass)[name]
    raise AssertionError(f"{cls.__name__}.{name} is declared in the stubs but missing at run time")


def test_the_stubs_declare_no_private_names(stubs):
    private = sorted({n for n in stubs.every_name() if n.startswith("_") and not is_dunder(n)})
    assert private == [], f"private names in {os.path.basename(STUBS)}: {private}"


def test_every_function_and_class_exists_with_the_stubs_docstring(stubs):
    for name, doc in stubs.functions.items():
        assert doc, f"the stub of {name} has no docstring"
        assert hasattr(stylerf, name), f"{name} is declared but not in stylerf"
        assert words(doc) in words(getattr(stylerf, name).__doc__), f"{name}: the stub's docstring differs from help()'s"
    for name, (doc, members) in stubs.classes.items():
        cls = getattr(stylerf, name, None)
        assert isinstance(cls, type), f"class {name} is declared but not in stylerf"
        assert doc, f"the stub of class {name} has no docstring"
        assert words(doc) == words(cls.__doc__), f"{name}: the stub's docstring differs from help()'s"
        for member, mdoc in members.items():
            assert mdoc, f"the stub of {name}.{member} has no docstring"
            obj = runtime_member(cls, member)
            obj = getattr(obj, "__func__", obj)
            assert words(mdoc) in words(obj.__doc__), f"{name}.{member}: the stub's docstring differs from help()'s"


def test_the_types_exist_and_say_what_they_are(stubs):
    for name in stubs.reexports + stubs.variables:
        assert hasattr(stylerf, name), f"{name} is declared but not in stylerf"
    typed_dicts = [n for n in stubs.reexports if isinstance(getattr(stylerf, n), type)]
    assert {"RenderResult", "ConsistencyScore", "DensityProgress"} <= set(typed_dicts)
    for name in typed_dicts:
        assert words(getattr(stylerf, name).__doc__), f"{name} has no docstring"


def test_everything_public_at_run_time_is_declared(stubs):
    declared = stubs.public_names()
    assert sorted(set(stylerf.__all__) - declared) == []
    for name, (_, members) in stubs.classes.items():
        cls = getattr(stylerf, name)
        public = {m for m in vars(cls) if not m.startswith("_")}
        if issubclass(cls, BaseException):
            continue
        assert sorted(public - set(members)) == [], f"{name} has members the stubs do not declare"


def test_help_shows_the_docstrings(capsys):
    help(stylerf.StyleModel.stylize)
    shown = words(capsys.readouterr().out)
    assert "stylize(self" in shown and "The view stylised with code" in shown
    page = words(pydoc.plain(pydoc.render_doc(stylerf.StyleModel)))
    assert "A trained style checkpoint on the scene it was trained on" in page
    assert "Opens a train_style checkpoint" in page
    assert "_cpp_stylize_seconds" not in page
