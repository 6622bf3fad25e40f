"""The type stubs (robimu/__init__.pyi, robimu/_native.pyi) state every
public name with the signature it has at run time, and a docstring."""

import ast
import inspect
from pathlib import Path

import pytest

import robimu
from robimu import _native

PKG = Path(robimu.__file__).parent


def stub(name):
    return ast.parse((PKG / name).read_text())


def defs(tree):
    """Top-level functions and classes (with their methods) of a stub, and
    the names it re-exports (`from m import X as X`)."""
    out = {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            out[node.name] = node
        elif isinstance(node, ast.ImportFrom):
            out.update({a.name: None for a in node.names if a.asname == a.name})
    return out


def params(fn):
    a = fn.args
    return [x.arg for x in a.posonlyargs + a.args] + (["*" + a.vararg.arg] if a.vararg else []) \
        + [x.arg for x in a.kwonlyargs] + (["**" + a.kwarg.arg] if a.kwarg else [])


def runtime_params(obj):
    out = []
    for p in inspect.signature(obj).parameters.values():
        prefix = {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}.get(p.kind, "")
        out.append(prefix + p.name)
    return out


def methods(cls):
    return {n.name: n for n in cls.body if isinstance(n, ast.FunctionDef)}


@pytest.mark.parametrize("module,file", [(robimu, "__init__.pyi"), (_native, "_native.pyi")])
def test_every_public_name_is_in_the_stub_with_its_signature(module, file):
    d = defs(stub(file))
    names = module.__all__ if hasattr(module, "__all__") else [n for n in dir(module) if not n.startswith("_")]
    missing = []
    for name in names:
        obj = getattr(module, name)
        if not (inspect.isclass(obj) or callable(obj)):
            continue
        if name not in d:
            missing.append(name)
            continue
        node = d[name]
        if node is None:  # re-exported: checked in its own module's stub
            continue
        assert ast.get_docstring(node), f"{file}: {name} has no docstring"
        if inspect.isclass(obj):
            if issubclass(obj, BaseException):
                continue
            ms = methods(node)
            for attr, val in vars(obj).items():
                if attr.startswith("_") or not callable(val) or isinstance(val, type):
                    continue
                assert attr in ms, f"{file}: {name}.{attr} missing"
                try:
                    rt = runtime_params(getattr(obj, attr))
                except (TypeError, ValueError):
                    continue
                st = [p for p in params(ms[attr]) if p not in ("self", "cls")]
                rt = [p for p in rt if p not in ("self", "cls", "$self", "$cls")]
                assert st == rt, f"{file}: {name}.{attr}{st} vs {rt}"
        else:
            try:
                rt = runtime_params(obj)
            except (TypeError, ValueError):
                continue
            assert params(node) == rt, f"{file}: {name}{params(node)} vs {rt}"
    assert not missing, f"{file} lacks {missing}"
