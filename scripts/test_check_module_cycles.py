#!/usr/bin/env python3
"""Self-test of check_module_cycles.py on tiny fake crates (stdlib unittest).

    python3 scripts/test_check_module_cycles.py
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
import tempfile
import textwrap
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
CHECKER = os.path.join(HERE, "check_module_cycles.py")

sys.dont_write_bytecode = True  # no __pycache__ left in scripts/
_spec = importlib.util.spec_from_file_location("check_module_cycles", CHECKER)
cmc = importlib.util.module_from_spec(_spec)
sys.modules["check_module_cycles"] = cmc
_spec.loader.exec_module(cmc)

CYCLE_RE = re.compile(r"^  CYCLE among (.+?) of crate (\S+): (.+)$")


def write_tree(root: str, files: dict[str, str]) -> None:
    for rel, text in files.items():
        path = os.path.join(root, rel)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(textwrap.dedent(text).lstrip("\n"))


def package(name: str) -> str:
    return f'[package]\nname = "{name}"\nversion = "0.1.0"\nedition = "2021"\n'


class Workspace:
    """A temporary workspace: {crate dir: {path under the crate: text}}."""

    def __init__(self, crates: dict[str, dict[str, str]]):
        self.tmp = tempfile.TemporaryDirectory()
        self.root = self.tmp.name
        members = ", ".join(f'"{c}"' for c in crates)
        write_tree(self.root, {"Cargo.toml": f"[workspace]\nmembers = [{members}]\n"})
        for crate, files in crates.items():
            write_tree(os.path.join(self.root, crate),
                       {"Cargo.toml": package(crate), **files})

    def run(self, *args: str) -> tuple[int, str]:
        proc = subprocess.run(
            [sys.executable, CHECKER, "--no-cargo", "--root", self.root, *args],
            capture_output=True, text=True, cwd=self.root)
        return proc.returncode, proc.stdout + proc.stderr

    def cycles(self, *args: str) -> tuple[int, set[tuple[str, str, frozenset]], str]:
        rc, out = self.run(*args)
        found = set()
        for line in out.splitlines():
            m = CYCLE_RE.match(line)
            if m:
                found.add((m.group(2), m.group(1), frozenset(m.group(3).split(", "))))
        return rc, found, out

    def close(self) -> None:
        self.tmp.cleanup()


TOP = "top-level modules"


class TwoCycle(unittest.TestCase):
    def test_use_crate_both_ways(self):
        ws = Workspace({"two": {
            "src/lib.rs": """
                pub mod a;
                pub mod b;
                pub mod c;
                pub use a::A;
            """,
            "src/a.rs": """
                use crate::b::B;
                pub struct A(pub B);
            """,
            "src/b.rs": """
                use crate::a;
                pub struct B;
                pub fn f() -> usize { std::mem::size_of::<a::A>() }
            """,
            "src/c.rs": "use crate::a::A;\n",
        }})
        try:
            rc, found, out = ws.cycles()
            self.assertEqual(rc, 1, out)
            self.assertEqual(found, {("two", TOP, frozenset({"a", "b"}))}, out)
            self.assertIn("a -> b  two/src/a.rs:1", out)
            self.assertIn("b -> a  two/src/b.rs:1", out)
            self.assertIn("crate two: 3 modules, 3 edges, 1 cycle", out)
        finally:
            ws.close()


class ThreeCycle(unittest.TestCase):
    """p -> q -> r -> p through super:: paths and a grouped multi-line use."""

    FILES = {
        "src/lib.rs": """
            mod p;
            pub(crate) mod q;
            pub mod r;
            pub mod util;
        """,
        # super:: from a top-level module's file is the crate root.
        "src/p.rs": """
            pub struct P;
            pub fn f() { super::q::g(); }
        """,
        "src/q/mod.rs": """
            mod inner;
            pub fn g() {}
        """,
        # super::super:: from q/inner.rs is the crate root too.
        "src/q/inner.rs": """
            use super::super::r::R;
            pub fn h(_: R) {}
        """,
        "src/r.rs": """
            use crate::{
                util,
                p::{
                    P,
                    f,
                },
            };
            pub struct R;
        """,
        "src/util.rs": "pub fn u() {}\n",
    }

    def test_three_cycle(self):
        ws = Workspace({"three": self.FILES})
        try:
            rc, found, out = ws.cycles()
            self.assertEqual(rc, 1, out)
            self.assertEqual(found, {("three", TOP, frozenset({"p", "q", "r"}))}, out)
            # the example line of r -> p is the line naming `p` in the group
            self.assertIn("r -> p  three/src/r.rs:3", out)
            self.assertIn("q -> r  three/src/q/inner.rs:1", out)
            self.assertIn("cycle: p -> q -> r -> p", out)
        finally:
            ws.close()

    def test_verbose_lists_every_edge(self):
        ws = Workspace({"three": self.FILES})
        try:
            rc, out = ws.run("--verbose")
            edges = set(re.findall(r"^    (\w+) -> (\w+) ", out, re.M))
            self.assertEqual(edges, {("p", "q"), ("q", "r"), ("r", "p"), ("r", "util")}, out)
        finally:
            ws.close()


class Acyclic(unittest.TestCase):
    def test_comments_and_strings_are_not_references(self):
        ws = Workspace({"acyclic": {
            "src/lib.rs": "pub mod a;\npub mod b;\npub mod x;\n",
            "src/a.rs": r'''
                //! Uses [`crate::b`] in prose only.
                // use crate::b;
                /* use crate::b; /* nested */ crate::b::f(); */
                /// See [`crate::b::f`] and [super::b].
                /** crate::b */
                pub fn a() -> &'static str {
                    let _q = '"';
                    let _s = "crate::x \" crate::b";
                    let _r = r##"use crate::b; "# crate::b"##;
                    let _b = b"crate::b";
                    let _e = '\'';
                    let _x = "use super::b;";
                    #[doc = "crate::b"]
                    let _label: () = 'outer: loop { break 'outer; };
                    "crate::x"
                }
            ''',
            "src/b.rs": """
                use crate::a::a;
                pub fn f() -> &'static str { a() }
            """,
            "src/x.rs": "pub fn x() {}\n",
        }})
        try:
            rc, found, out = ws.cycles("--verbose")
            self.assertEqual(rc, 0, out)
            self.assertEqual(found, set(), out)
            edges = set(re.findall(r"^    (\w+) -> (\w+) ", out, re.M))
            self.assertEqual(edges, {("b", "a")}, out)
            self.assertIn("crate acyclic: 3 modules, 1 edge, no cycles", out)
            self.assertIn("OK: no module cycles", out)
        finally:
            ws.close()


class Nested(unittest.TestCase):
    FILES = {
        "src/lib.rs": "pub mod m;\npub mod other;\n",
        "src/m/mod.rs": """
            pub mod x;
            pub mod y;
            pub mod z;
            pub use x::X;
        """,
        "src/m/x.rs": "use super::y::Y;\npub struct X;\n",
        "src/m/y.rs": "pub struct Y;\npub fn f() -> crate::m::x::X { crate::m::x::X }\n",
        # #[path] and an inline test module resolving super relative to itself
        "src/m/z.rs": """
            pub struct Z;
            #[cfg(test)]
            #[path = "z_tests.rs"]
            mod tests;
        """,
        "src/m/z_tests.rs": "use super::super::x::X;\n",
        "src/other.rs": """
            pub fn o() {}
            #[cfg(test)]
            mod tests {
                use super::super::m::z;
            }
        """,
    }

    def test_cycle_among_children(self):
        ws = Workspace({"nested": dict(self.FILES)})
        try:
            rc, found, out = ws.cycles("--verbose")
            self.assertEqual(rc, 1, out)
            self.assertEqual(found, {("nested", "submodules of m", frozenset({"m::x", "m::y"}))},
                             out)
            self.assertIn("m::z -> m::x  nested/src/m/z_tests.rs:1", out)
            self.assertIn("other -> m  nested/src/other.rs:4  names m::z", out)
        finally:
            ws.close()

    def test_test_only_cycle_and_ignore_tests(self):
        files = dict(self.FILES)
        files["src/m/y.rs"] = "pub struct Y;\n"
        # m::x -> m::z only from test code: a cycle by default, none without tests
        files["src/m/x.rs"] = """
            use super::y::Y;
            pub struct X;
            #[cfg(test)]
            mod tests {
                use super::super::z::Z;
            }
        """
        files["src/m/z.rs"] = "pub struct Z;\nmod helper;\n"
        files["src/m/z/helper.rs"] = "pub fn h() {}\n#[cfg(test)]\nmod tests;\n"
        files["src/m/z/helper/tests.rs"] = "use crate::m::x::X;\n"
        ws = Workspace({"nested": files})
        try:
            rc, found, out = ws.cycles()
            self.assertEqual(rc, 1, out)
            self.assertEqual(found, {("nested", "submodules of m", frozenset({"m::x", "m::z"}))},
                             out)
            self.assertIn("(test code only)", out)
            rc, found, out = ws.cycles("--ignore-tests")
            self.assertEqual((rc, found), (0, set()), out)
        finally:
            ws.close()


class RootReexports(unittest.TestCase):
    """`crate::Foo` through `pub use a::Foo` in lib.rs is an edge to `a`."""

    FILES = {
        "src/lib.rs": """
            pub mod a;
            pub mod b;
            pub mod c;
            pub mod d;
            pub use a::{
                Alpha,
                inner::{self as deep, Deep as D},
            };
            pub use self::c::Gamma;
            pub use Gamma as G2;
            pub use serde::Serialize;
        """,
        "src/a.rs": """
            pub mod inner;
            use crate::b::Beta;
            pub struct Alpha(pub Beta);
        """,
        "src/a/inner.rs": "pub struct Deep;\n",
        # b -> a only through the root's re-export
        "src/b.rs": """
            pub struct Beta;
            pub fn f(_: &crate::Alpha) {}
        """,
        "src/c.rs": """
            pub struct Gamma;
            pub fn g() -> crate::D { crate::deep::Deep }
        """,
        # a chain (G2 -> Gamma -> c::Gamma) and an external crate's name
        "src/d.rs": """
            use crate::{G2, Serialize};
        """,
    }

    def test_reexported_names_count_to_their_module(self):
        ws = Workspace({"reexp": self.FILES})
        try:
            rc, found, out = ws.cycles("--verbose")
            self.assertEqual(rc, 1, out)
            self.assertEqual(found, {("reexp", TOP, frozenset({"a", "b"}))}, out)
            edges = set(re.findall(r"^    (\w+) -> (\w+) ", out, re.M))
            self.assertEqual(edges, {("a", "b"), ("b", "a"), ("c", "a"), ("d", "c")}, out)
            self.assertIn("b -> a  reexp/src/b.rs:2", out)
            self.assertRegex(out, r"c -> a +reexp/src/c.rs:2  names a::inner")
        finally:
            ws.close()

    def test_imports_of_a_file(self):
        parsed = cmc.parse_source(
            "pub use a::{self, b::{C, D as E}, f::*};\n"
            "pub(crate) use crate::g::H as _;\n"
            "fn k() { use crate::l::M; }\n")
        imports = [(i.name, [s for s, _ in i.segs]) for i in parsed.imports]
        self.assertEqual(imports, [("a", ["a"]), ("C", ["a", "b", "C"]),
                                   ("E", ["a", "b", "D"])])


class Lexer(unittest.TestCase):
    def idents(self, src: str) -> list[str]:
        return [t.value for t in cmc.lex(src) if t.kind == "ident"]

    def test_literals_and_comments(self):
        src = r'''a /* b /* c */ d */ e "f \" g" h r##"i "# j"## k '"' l 'm' 'n: o '\'' p // q
        r b"s" t br#"u"# v'''
        self.assertEqual(self.idents(src), ["a", "e", "h", "k", "l", "o", "p", "r", "t", "v"])

    def test_line_numbers_survive_multiline_literals(self):
        toks = cmc.lex('x\n"a\nb"\n/* c\n d */ y\nz')
        self.assertEqual([(t.value, t.line) for t in toks if t.kind == "ident"],
                         [("x", 1), ("y", 5), ("z", 6)])

    def test_use_groups_and_dollar_crate(self):
        parsed = cmc.parse_source(
            "use crate::{a::{self, b}, c as d, e::*};\n"
            "macro_rules! m { () => { $crate::zz::f() } }\n"
            "fn g() { crate::h::i(); ::std::mem::drop(self::j::k); }\n",
            ("top",))
        paths = [[s for s, _ in r.segs] for r in parsed.refs]
        self.assertEqual(paths, [["crate", "a"], ["crate", "a", "b"], ["crate", "c"],
                                 ["crate", "e"], ["crate", "h", "i"], ["self", "j", "k"]])


if __name__ == "__main__":
    unittest.main(verbosity=2)
