#!/usr/bin/env python3
"""Check that no crate in the workspace has import cycles between its modules.

For every library and binary target ("crate") of every workspace package the
checker walks the module tree from the crate root (`mod x;` declarations,
`#[path = "..."]` attributes, inline `mod x { ... }` blocks), collects every
path that names a module of the same crate (`crate::...`, `super::...`,
`self::...`, in `use` trees -- grouped and multi-line ones too -- and inline in
code), and builds, for every module M that has submodules, the directed graph
among M's children: child A -> child B when code in a file under A names
something under B. The graph among the top-level modules is the one for the
crate root (the root file itself is not a node: lib.rs usually re-exports
everything). Every strongly connected component with more than one module is
an import cycle; each one is reported with one example `file:line` per edge.

Comments (line, block, doc) and string/char literals are ignored; so are
`$crate` paths and paths that do not start with `crate`, `super` or `self`
(external crates, and 2018-style relative paths, which can only name the
current module's own children and so never cross between siblings).

Inline modules belong to their enclosing file's module (they are not nodes of
their own), but `super::`/`self::` inside them are resolved relative to the
inline module, as rustc does (`mod tests { use super::super::x; }`).

Crates are found with `cargo metadata --no-deps --offline` (no build; falls
back to reading the Cargo.toml files when cargo is missing or fails, e.g. in a
half-moved tree). Extra positional arguments are more workspaces to check,
e.g. ones the main workspace `exclude`s:

    python3 scripts/check_module_cycles.py                  # the workspace
    python3 scripts/check_module_cycles.py firmware/boards  # ... and boards
    python3 scripts/check_module_cycles.py --verbose --ignore-tests
    python3 scripts/check_module_cycles.py --no-cargo       # never run cargo

Output: one line per crate, `crate NAME: N modules, E edges, no cycles`
(N and E count the top-level modules and the edges among them; `[nested:
...]` counts the levels below), then for every cycle its modules, every edge
inside it with one example `file:line` (preferring non-test code) and what the
path names, and a few shortest cycles through it. `--verbose` lists every edge.

Re-exports are followed: a path through a name that a module file brings in
with a top-level `use` (`pub use a::Foo;`, `pub use self::a::{Foo, b::Bar as
Baz};`, ...; in lib.rs/main.rs or in M's own file) counts as a reference to
the module the name comes from, so `crate::Foo` where lib.rs has `pub use
a::Foo` is an edge to `a` (chains of re-exports too).

Known blind spots: names brought in by glob re-exports (`pub use a::*`) are
not followed (the path counts as a reference to the module holding the glob);
module aliases (`use crate::a as x; x::b::f()`) count only as the `use`;
macros are not expanded.

Exit status: 0 no cycles, 1 at least one cycle, 2 nothing to check / bad
usage. Python 3.11+, standard library only.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
from collections import deque
from dataclasses import dataclass, field

# --------------------------------------------------------------------------
# Lexer: just enough Rust to drop comments and literals and keep line numbers.
# --------------------------------------------------------------------------

_IDENT_RE = re.compile(r"[^\W\d]\w*")
_RAW_STR_RE = re.compile(r'(?:br|cr|r)(#*)"')
_NUM_RE = re.compile(r"\d\w*(?:\.\d\w*)?")
_LIFETIME_RE = re.compile(r"'[^\W\d]\w*")


@dataclass(slots=True)
class Tok:
    kind: str  # "ident", "punct", "str", "char", "lifetime", "num", "eof"
    value: str
    line: int


def lex(text: str) -> list[Tok]:
    """Tokens of Rust source `text`, without comments; literals kept as one token."""
    toks: list[Tok] = []
    i, n, line = 0, len(text), 1
    append = toks.append
    while i < n:
        c = text[i]
        if c == "\n":
            line += 1
            i += 1
            continue
        if c.isspace():
            i += 1
            continue
        if c == "/" and i + 1 < n and text[i + 1] == "/":
            j = text.find("\n", i)
            i = n if j < 0 else j
            continue
        if c == "/" and i + 1 < n and text[i + 1] == "*":
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth += 1
                    j += 2
                elif text.startswith("*/", j):
                    depth -= 1
                    j += 2
                else:
                    j += 1
            line += text.count("\n", i, j)
            i = j
            continue
        if c in "rbc":
            m = _RAW_STR_RE.match(text, i)
            if m:
                close = '"' + m.group(1)
                j = text.find(close, m.end())
                j = n if j < 0 else j
                val = text[m.end() : j]
                append(Tok("str", val, line))
                line += val.count("\n")
                i = j + len(close)
                continue
            if c == "r" and text.startswith("r#", i):  # raw identifier r#name
                m = _IDENT_RE.match(text, i + 2)
                if m:
                    append(Tok("ident", m.group(0), line))
                    i = m.end()
                    continue
        if c == '"' or (c in "bc" and i + 1 < n and text[i + 1] == '"'):
            start = i + 1 if c == '"' else i + 2
            j = start
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            val = text[start:j]
            append(Tok("str", val, line))
            line += val.count("\n")
            i = j + 1
            continue
        if c == "'" or (c == "b" and i + 1 < n and text[i + 1] == "'"):
            k = i if c == "'" else i + 1
            if k + 1 < n and text[k + 1] == "\\":  # escaped char literal
                j = k + 1
                while j < n and text[j] != "'" and text[j] != "\n":
                    j += 2 if text[j] == "\\" else 1
                append(Tok("char", text[k + 1 : j], line))
                i = j + 1
                continue
            if k + 2 < n and text[k + 2] == "'" and text[k + 1] != "\n":
                append(Tok("char", text[k + 1], line))
                i = k + 3
                continue
            m = _LIFETIME_RE.match(text, k)
            if m and c == "'":
                append(Tok("lifetime", m.group(0), line))
                i = m.end()
                continue
            # lone quote (or `b` followed by one): fall through as punct/ident
        m = _IDENT_RE.match(text, i)
        if m:
            append(Tok("ident", m.group(0), line))
            i = m.end()
            continue
        if c.isdigit():
            m = _NUM_RE.match(text, i)
            append(Tok("num", m.group(0), line))
            i = m.end()
            continue
        if c == ":" and i + 1 < n and text[i + 1] == ":":
            append(Tok("punct", "::", line))
            i += 2
            continue
        append(Tok("punct", c, line))
        i += 1
    append(Tok("eof", "", line))
    return toks


# --------------------------------------------------------------------------
# Parser: module declarations and module paths of one file.
# --------------------------------------------------------------------------

PREFIXES = ("crate", "super", "self")
MAX_EXAMPLE_CYCLES = 6


@dataclass
class ModDecl:
    name: str
    line: int
    path_attr: str | None
    inline_dirs: tuple[str, ...]  # directory components of enclosing inline mods
    inline_names: tuple[str, ...]  # names of enclosing inline mods
    is_test: bool


@dataclass
class Ref:
    full_src: tuple[str, ...]  # module path incl. inline modules (for super/self)
    segs: list[tuple[str, int]]  # the path as written: (segment, line)
    in_test: bool


@dataclass
class Import:
    """A name a file's module brings in with a top-level `use`: `as` `path`."""
    name: str
    segs: list[tuple[str, int]]  # the path as written (relative ones too)


@dataclass
class ParsedFile:
    decls: list[ModDecl] = field(default_factory=list)
    refs: list[Ref] = field(default_factory=list)
    imports: list[Import] = field(default_factory=list)  # top-level `use` names
    file_is_test: bool = False  # `#![cfg(test)]` at the top


def _is_cfg_test(attr: list[Tok]) -> bool:
    """`#[cfg(test)]`, `#[cfg(all(test, ...))]` (not `not(test)`, not `any(...)`)."""
    if not attr or attr[0].value != "cfg":
        return False
    words = {t.value for t in attr if t.kind == "ident"}
    return "test" in words and "not" not in words and "any" not in words


def _path_attr(attrs: list[list[Tok]]) -> str | None:
    for attr in attrs:
        if (
            len(attr) >= 3
            and attr[0].value == "path"
            and attr[1].value == "="
            and attr[2].kind == "str"
        ):
            return attr[2].value
    return None


class _FileParser:
    def __init__(self, toks: list[Tok], mod_path: tuple[str, ...], file_is_test: bool,
                 ignore_tests: bool):
        self.t = toks
        self.mod_path = mod_path
        self.ignore_tests = ignore_tests
        self.out = ParsedFile(file_is_test=file_is_test)
        # Brace stack entries: None for ordinary braces, or (name, dir, is_test)
        # for inline modules.
        self.stack: list[tuple[str, str, bool] | None] = []

    # -- helpers ---------------------------------------------------------
    def _inline(self) -> list[tuple[str, str, bool]]:
        return [e for e in self.stack if e is not None]

    def _in_test(self) -> bool:
        return self.out.file_is_test or any(e[2] for e in self._inline())

    def _full_src(self) -> tuple[str, ...]:
        return self.mod_path + tuple(e[0] for e in self._inline())

    def _skip_group(self, i: int, open_: str, close: str) -> int:
        """`i` at an opening delimiter: index after its matching close."""
        depth = 0
        t = self.t
        while t[i].kind != "eof":
            if t[i].kind == "punct":
                if t[i].value == open_:
                    depth += 1
                elif t[i].value == close:
                    depth -= 1
                    if depth == 0:
                        return i + 1
            i += 1
        return i

    def _is(self, i: int, kind: str, value: str | None = None) -> bool:
        tok = self.t[i]
        return tok.kind == kind and (value is None or tok.value == value)

    # -- use trees and paths --------------------------------------------
    def _use_tree(self, i: int) -> tuple[list[tuple[list[tuple[str, int]], str]], int]:
        """Parse one use tree at `i`: (leaves, index after the tree).

        A leaf is its path and the name it binds: the last segment, the `as`
        name, `*` for a glob (`_` binds nothing).
        """
        t = self.t
        prefix: list[tuple[str, int]] = []
        if self._is(i, "punct", "::"):
            i += 1
            prefix.append(("::", t[i].line))  # extern-crate path: never resolved
        while True:
            tok = t[i]
            if tok.kind == "ident":
                prefix.append((tok.value, tok.line))
                i += 1
                if self._is(i, "punct", "::"):
                    i += 1
                    continue
                bound = tok.value
                if self._is(i, "ident", "as"):
                    bound = t[i + 1].value
                    i += 2
                return [(prefix, bound)], i
            if self._is(i, "punct", "*"):
                return [(prefix, "*")], i + 1
            if self._is(i, "punct", "{"):
                i += 1
                out: list[tuple[list[tuple[str, int]], str]] = []
                while not self._is(i, "punct", "}") and t[i].kind != "eof":
                    start = i
                    subs, i = self._use_tree(i)
                    for s, bound in subs:
                        if prefix and s and s[0][0] == "self":  # `{self, ...}`
                            if bound == "self":
                                bound = prefix[-1][0]
                            out.append((prefix + s[1:], bound))
                        else:
                            out.append((prefix + s, bound))
                    if self._is(i, "punct", ","):
                        i += 1
                    elif i == start or not self._is(i, "punct", "}"):
                        i += 1  # malformed: make progress
                return out, i + 1
            return ([(prefix, prefix[-1][0])] if prefix else []), i

    def _add_ref(self, segs: list[tuple[str, int]]) -> None:
        if segs and segs[0][0] in PREFIXES:
            self.out.refs.append(Ref(self._full_src(), segs, self._in_test()))

    def _inline_path(self, i: int) -> int:
        """`i` at `crate`/`super`/`self` followed by `::`: record the path."""
        t = self.t
        segs = [(t[i].value, t[i].line)]
        i += 1
        while self._is(i, "punct", "::") and self._is(i + 1, "ident"):
            segs.append((t[i + 1].value, t[i + 1].line))
            i += 2
        self._add_ref(segs)
        return i

    # -- main loop --------------------------------------------------------
    def parse(self) -> ParsedFile:
        t = self.t
        i = 0
        attrs: list[list[Tok]] = []
        prev: Tok | None = None
        while t[i].kind != "eof":
            tok = t[i]
            # Attributes: collect, they apply to the next item.
            if tok.kind == "punct" and tok.value == "#":
                inner = self._is(i + 1, "punct", "!")
                j = i + 2 if inner else i + 1
                if self._is(j, "punct", "["):
                    end = self._skip_group(j, "[", "]")
                    attr = t[j + 1 : end - 1]
                    if inner:
                        if not self.stack and _is_cfg_test(attr):
                            self.out.file_is_test = True
                            if self.ignore_tests:
                                return self.out
                    else:
                        attrs.append(attr)
                    prev, i = t[end - 1], end
                    continue
            if tok.kind == "ident" and tok.value == "pub":
                if self._is(i + 1, "punct", "("):
                    i = self._skip_group(i + 1, "(", ")")
                else:
                    i += 1
                prev = t[i - 1]
                continue  # visibility keeps the pending attributes
            pending, attrs = attrs, []
            is_test = any(_is_cfg_test(a) for a in pending)

            if tok.kind == "ident" and tok.value == "mod" and self._is(i + 1, "ident"):
                name = t[i + 1].value
                if self._is(i + 2, "punct", ";"):
                    inl = self._inline()
                    self.out.decls.append(ModDecl(
                        name, tok.line, _path_attr(pending),
                        tuple(e[1] for e in inl), tuple(e[0] for e in inl),
                        is_test or self._in_test()))
                    prev, i = t[i + 2], i + 3
                    continue
                if self._is(i + 2, "punct", "{"):
                    if is_test and self.ignore_tests:
                        i = self._skip_group(i + 2, "{", "}")
                        prev = t[i - 1]
                        continue
                    self.stack.append((name, _path_attr(pending) or name, is_test))
                    prev, i = t[i + 2], i + 3
                    continue
            if tok.kind == "ident" and tok.value == "use" and not (
                prev is not None and prev.kind == "punct" and prev.value in ("::", "$")
            ):
                if is_test and self.ignore_tests:
                    while not self._is(i, "punct", ";") and t[i].kind != "eof":
                        i += 1
                    continue
                leaves, i = self._use_tree(i + 1)
                for p, bound in leaves:
                    self._add_ref(p)
                    if not self.stack and p and bound not in ("*", "_", "self"):
                        self.out.imports.append(Import(bound, p))
                prev = t[i - 1]
                continue
            if (
                tok.kind == "ident"
                and tok.value in PREFIXES
                and self._is(i + 1, "punct", "::")
                and not (prev is not None and prev.kind == "punct"
                         and prev.value in ("::", "$"))
            ):
                i = self._inline_path(i)
                prev = t[i - 1]
                continue
            if tok.kind == "punct" and tok.value == "{":
                self.stack.append(None)
            elif tok.kind == "punct" and tok.value == "}":
                if self.stack:
                    self.stack.pop()
            prev = tok
            i += 1
        return self.out


def parse_source(text: str, mod_path: tuple[str, ...] = (), file_is_test: bool = False,
                 ignore_tests: bool = False) -> ParsedFile:
    return _FileParser(lex(text), mod_path, file_is_test, ignore_tests).parse()


def resolve(ref: Ref) -> list[tuple[str, int]] | None:
    """Absolute module path (from the crate root) of a reference, or None."""
    segs = ref.segs
    first, line = segs[0]
    if first == "crate":
        base: tuple[str, ...] = ()
        rest = segs[1:]
    elif first == "self":
        base, rest = ref.full_src, segs[1:]
    elif first == "super":
        base, k = ref.full_src, 0
        while k < len(segs) and segs[k][0] == "super":
            if not base:
                return None  # beyond the crate root: not valid Rust
            base, k = base[:-1], k + 1
        rest = segs[k:]
    else:
        return None
    if any(s in PREFIXES for s, _ in rest):
        return None  # `crate::a::super`, `self::super::x`: not module paths we resolve
    return [(b, line) for b in base] + list(rest)


# --------------------------------------------------------------------------
# Crates and their module trees.
# --------------------------------------------------------------------------

def is_test_file_name(path: str) -> bool:
    base = os.path.basename(path)
    return base == "tests.rs" or base.endswith("_tests.rs")


@dataclass
class ModFile:
    path: str
    mod_path: tuple[str, ...]
    parsed: ParsedFile


@dataclass
class Crate:
    name: str
    root: str
    files: list[ModFile] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


def load_crate(name: str, root_file: str, ignore_tests: bool, rel) -> Crate:
    crate = Crate(name, root_file)
    seen: set[str] = set()
    # (file, module path, is mod-rs for nested `mod x;` lookups, is test)
    queue = deque([(root_file, (), True, False)])
    while queue:
        path, mod_path, mod_rs, is_test = queue.popleft()
        real = os.path.realpath(path)
        if real in seen:
            crate.warnings.append(f"{rel(path)} is loaded twice; skipped the second time")
            continue
        seen.add(real)
        try:
            with open(path, encoding="utf-8", errors="replace") as fh:
                text = fh.read()
        except OSError as e:
            crate.warnings.append(f"cannot read {rel(path)}: {e}")
            continue
        parsed = parse_source(text, mod_path, is_test, ignore_tests)
        if parsed.file_is_test and ignore_tests:
            continue
        crate.files.append(ModFile(path, mod_path, parsed))
        here = os.path.dirname(path)
        if mod_rs:
            own_dir = here
        else:
            own_dir = os.path.join(here, os.path.splitext(os.path.basename(path))[0])
        for d in parsed.decls:
            if d.is_test and ignore_tests:
                continue
            child_path = mod_path + d.inline_names + (d.name,)
            if d.path_attr is not None:
                base = here if not d.inline_dirs else os.path.join(own_dir, *d.inline_dirs)
                candidates = [os.path.normpath(os.path.join(base, d.path_attr))]
            else:
                base = os.path.join(own_dir, *d.inline_dirs)
                candidates = [os.path.join(base, d.name + ".rs"),
                              os.path.join(base, d.name, "mod.rs")]
            found = next((c for c in candidates if os.path.isfile(c)), None)
            if found is None:
                crate.warnings.append(
                    f"{rel(path)}:{d.line}: `mod {d.name};` has no file "
                    f"(looked for {', '.join(rel(c) for c in candidates)})")
                continue
            child_test = d.is_test or is_test_file_name(found)
            if child_test and ignore_tests:
                continue
            child_mod_rs = d.path_attr is not None or os.path.basename(found) == "mod.rs"
            queue.append((found, child_path, child_mod_rs, child_test))
    return crate


@dataclass
class Target:
    name: str  # display name of the crate
    src: str


_LIB_KINDS = {"lib", "rlib", "dylib", "cdylib", "staticlib", "proc-macro"}


def _target_name(pkg: str, kind: str, tname: str) -> str:
    return pkg if kind == "lib" else f"{pkg} [bin {tname}]"


def targets_from_cargo(ws: str, note) -> list[Target] | None:
    cargo = shutil.which("cargo")
    manifest = os.path.join(ws, "Cargo.toml")
    if cargo is None or not os.path.isfile(manifest):
        return None
    cmd = [cargo, "metadata", "--no-deps", "--format-version", "1", "--offline",
           "--manifest-path", manifest]
    try:
        proc = subprocess.run(cmd, cwd=ws, capture_output=True, text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as e:
        note(f"cargo metadata failed ({e}); reading Cargo.toml files instead")
        return None
    if proc.returncode != 0:
        msg = next((ln for ln in proc.stderr.splitlines() if ln.strip()), "no message")
        note(f"cargo metadata failed ({msg.strip()}); reading Cargo.toml files instead")
        return None
    try:
        meta = json.loads(proc.stdout)
    except json.JSONDecodeError as e:
        note(f"cargo metadata printed no JSON ({e}); reading Cargo.toml files instead")
        return None
    members = set(meta.get("workspace_members", []))
    out = []
    for pkg in meta.get("packages", []):
        if members and pkg.get("id") not in members:
            continue
        for tgt in pkg.get("targets", []):
            kinds = set(tgt.get("kind", []))
            if kinds & _LIB_KINDS:
                out.append(Target(_target_name(pkg["name"], "lib", tgt["name"]), tgt["src_path"]))
            elif "bin" in kinds:
                out.append(Target(_target_name(pkg["name"], "bin", tgt["name"]), tgt["src_path"]))
    return out


def _read_toml(path: str, note) -> dict | None:
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except (OSError, tomllib.TOMLDecodeError) as e:
        note(f"cannot read {path}: {e}")
        return None


def _package_targets(pkg_dir: str, manifest: dict) -> list[Target]:
    pkg = manifest["package"]
    pname = pkg.get("name", os.path.basename(pkg_dir))
    out: list[Target] = []
    lib = manifest.get("lib", {})
    lib_path = os.path.join(pkg_dir, lib.get("path", os.path.join("src", "lib.rs")))
    if os.path.isfile(lib_path):
        out.append(Target(_target_name(pname, "lib", pname), lib_path))
    seen = set()
    for b in manifest.get("bin", []):
        bname = b.get("name", pname)
        if "path" in b:
            p = os.path.join(pkg_dir, b["path"])
        else:
            cands = [os.path.join(pkg_dir, "src", "bin", bname + ".rs"),
                     os.path.join(pkg_dir, "src", "bin", bname, "main.rs")]
            if bname == pname:
                cands.insert(0, os.path.join(pkg_dir, "src", "main.rs"))
            p = next((c for c in cands if os.path.isfile(c)), cands[0])
        if os.path.isfile(p):
            out.append(Target(_target_name(pname, "bin", bname), p))
            seen.add(os.path.realpath(p))
    if pkg.get("autobins", True) is not False:
        auto = []
        main = os.path.join(pkg_dir, "src", "main.rs")
        if os.path.isfile(main):
            auto.append((pname, main))
        for p in sorted(glob.glob(os.path.join(pkg_dir, "src", "bin", "*.rs"))):
            auto.append((os.path.splitext(os.path.basename(p))[0], p))
        for p in sorted(glob.glob(os.path.join(pkg_dir, "src", "bin", "*", "main.rs"))):
            auto.append((os.path.basename(os.path.dirname(p)), p))
        for bname, p in auto:
            if os.path.realpath(p) not in seen:
                out.append(Target(_target_name(pname, "bin", bname), p))
                seen.add(os.path.realpath(p))
    return out


def targets_from_manifests(ws: str, note) -> list[Target]:
    """Workspace members (globs) plus any package below `ws` outside nested workspaces."""
    ws = os.path.abspath(ws)
    root = _read_toml(os.path.join(ws, "Cargo.toml"), note) or {}
    wsp = root.get("workspace", {})
    exclude = {os.path.normpath(os.path.join(ws, e)) for e in wsp.get("exclude", [])}
    pkg_dirs: list[str] = []
    if "package" in root:
        pkg_dirs.append(ws)
    for m in wsp.get("members", []):
        matches = sorted(glob.glob(os.path.join(ws, m)))
        if not any(os.path.isfile(os.path.join(d, "Cargo.toml")) for d in matches):
            note(f"workspace member {m!r} has no Cargo.toml (moved?)")
        pkg_dirs += [d for d in matches if os.path.isfile(os.path.join(d, "Cargo.toml"))]
    # Packages not (yet) listed as members: a tree in the middle of a move.
    for dirpath, dirnames, filenames in os.walk(ws):
        keep = []
        for d in sorted(dirnames):
            full = os.path.join(dirpath, d)
            if d.startswith(".") or d == "target" or os.path.normpath(full) in exclude:
                continue
            keep.append(d)
        dirnames[:] = keep
        if dirpath != ws and "Cargo.toml" in filenames:
            m = _read_toml(os.path.join(dirpath, "Cargo.toml"), note) or {}
            if "workspace" in m:  # a nested workspace of its own: pass it as an argument
                dirnames[:] = []
                continue
            if "package" in m:
                if os.path.normpath(dirpath) not in {os.path.normpath(d) for d in pkg_dirs}:
                    note(f"package in {os.path.relpath(dirpath, ws)} is not a workspace "
                         f"member; checked anyway")
                pkg_dirs.append(dirpath)
    out: list[Target] = []
    done = set()
    for d in pkg_dirs:
        d = os.path.normpath(d)
        if d in done:
            continue
        done.add(d)
        m = _read_toml(os.path.join(d, "Cargo.toml"), note)
        if m and "package" in m:
            out += _package_targets(d, m)
    return out


# --------------------------------------------------------------------------
# Graphs and cycles.
# --------------------------------------------------------------------------

@dataclass
class EdgeInfo:
    # (file, line, in test code, the module the reference names, e.g. "b::c")
    examples: list[tuple[str, int, bool, str]] = field(default_factory=list)

    def best(self) -> tuple[str, int, bool, str]:
        non_test = [e for e in self.examples if not e[2]]
        return min(non_test or self.examples)

    @property
    def test_only(self) -> bool:
        return all(e[2] for e in self.examples)


@dataclass
class Level:
    parent: tuple[str, ...]  # () is the crate root
    children: list[str]
    edges: dict[tuple[str, str], EdgeInfo] = field(default_factory=dict)


Reexports = dict[tuple[str, ...], dict[str, list[str]]]


def collect_reexports(crate: Crate, nodes: set[tuple[str, ...]]) -> Reexports:
    """Per module (the file's own, not inline ones): name -> absolute path it imports.

    Paths starting with `crate`/`self`/`super` are resolved as usual; other
    ones (2018-style relative paths) only when they start with a child module
    of the importing module or with another name it imports (otherwise they
    name an external crate).
    """
    out: Reexports = {}
    for f in crate.files:
        local = {imp.name for imp in f.parsed.imports}
        for imp in f.parsed.imports:
            first = imp.segs[0][0]
            if first in PREFIXES:
                target = resolve(Ref(f.mod_path, imp.segs, False))
                if target is None:
                    continue
                names = [s for s, _ in target]
            elif f.mod_path + (first,) in nodes or first in local:
                names = list(f.mod_path) + [s for s, _ in imp.segs]
            else:
                continue
            if names and names != list(f.mod_path) + [imp.name]:
                out.setdefault(f.mod_path, {})[imp.name] = names
    return out


MAX_REEXPORT_HOPS = 16


def follow_reexports(target: list[tuple[str, int]], reexports: Reexports,
                     nodes: set[tuple[str, ...]]) -> list[tuple[str, int]]:
    """`target` with every re-exported name on its module part replaced by its source."""
    for _ in range(MAX_REEXPORT_HOPS):
        prefix: tuple[str, ...] = ()
        for k, (seg, line) in enumerate(target):
            if prefix + (seg,) in nodes:
                prefix += (seg,)
                continue
            source = reexports.get(prefix, {}).get(seg)
            if source is None:
                return target
            target = [(s, line) for s in source] + target[k + 1:]
            break
        else:
            return target
    return target


def build_levels(crate: Crate) -> dict[tuple[str, ...], Level]:
    nodes: set[tuple[str, ...]] = set()
    for f in crate.files:
        for k in range(1, len(f.mod_path) + 1):
            nodes.add(f.mod_path[:k])
    reexports = collect_reexports(crate, nodes)
    levels: dict[tuple[str, ...], Level] = {}
    for node in sorted(nodes):
        parent = node[:-1]
        levels.setdefault(parent, Level(parent, [])).children.append(node[-1])
    for f in crate.files:
        src = f.mod_path  # inline modules belong to their file's module
        for ref in f.parsed.refs:
            target = resolve(ref)
            if target is None:
                continue
            target = follow_reexports(target, reexports, nodes)
            names = tuple(s for s, _ in target)
            for k in range(len(src)):
                parent = src[:k]
                if len(names) <= k or names[:k] != parent:
                    continue
                b = names[k]
                if parent + (b,) not in nodes:
                    continue
                a = src[k]
                if a == b:
                    continue
                depth = k + 1  # the deepest module the path names
                while depth < len(names) and names[: depth + 1] in nodes:
                    depth += 1
                levels[parent].edges.setdefault((a, b), EdgeInfo()).examples.append(
                    (f.path, target[k][1], ref.in_test, "::".join(names[:depth])))
    return levels


def strongly_connected(nodes: list[str], edges) -> list[list[str]]:
    """Tarjan's algorithm, iterative; components in discovery order."""
    succ: dict[str, list[str]] = {v: [] for v in nodes}
    for a, b in edges:
        succ.setdefault(a, []).append(b)
        succ.setdefault(b, [])
    for v in succ:
        succ[v].sort()
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    comps: list[list[str]] = []
    counter = 0
    for root in sorted(succ):
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            v, pi = work.pop()
            if pi == 0:
                index[v] = low[v] = counter
                counter += 1
                stack.append(v)
                on_stack.add(v)
            recurse = False
            for j in range(pi, len(succ[v])):
                w = succ[v][j]
                if w not in index:
                    work.append((v, j + 1))
                    work.append((w, 0))
                    recurse = True
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            if recurse:
                continue
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                comps.append(sorted(comp))
            if work:
                u = work[-1][0]
                low[u] = min(low[u], low[v])
    return comps


def shortest_cycle(start: str, members: set[str], edges) -> list[str]:
    """A shortest cycle through `start` inside one component."""
    succ: dict[str, list[str]] = {}
    for a, b in edges:
        if a in members and b in members:
            succ.setdefault(a, []).append(b)
    prev: dict[str, str] = {}
    q = deque([start])
    seen = {start}
    while q:
        v = q.popleft()
        for w in sorted(succ.get(v, [])):
            if w == start:
                path = [v]
                while path[-1] != start:
                    path.append(prev[path[-1]])
                return list(reversed(path)) + [start]
            if w not in seen:
                seen.add(w)
                prev[w] = v
                q.append(w)
    return [start]


# --------------------------------------------------------------------------
# Main.
# --------------------------------------------------------------------------

def _n(count: int, noun: str) -> str:
    return f"{count} {noun}{'' if count == 1 else 's'}"


def _qual(parent: tuple[str, ...], child: str) -> str:
    return "::".join(parent + (child,))


def check_crate(crate: Crate, verbose: bool, rel, out) -> int:
    levels = build_levels(crate)
    top = levels.get((), Level((), []))
    nested = [lv for p, lv in levels.items() if p]
    cycles = []  # (level, component)
    for p in sorted(levels):
        lv = levels[p]
        for comp in strongly_connected(lv.children, lv.edges):
            if len(comp) > 1:
                cycles.append((lv, comp))
    n_top = sum(1 for lv, _ in cycles if not lv.parent)
    n_nested = len(cycles) - n_top
    sub_mods = sum(len(lv.children) for lv in nested)
    sub_edges = sum(len(lv.edges) for lv in nested)
    if cycles:
        status = f"{len(cycles)} cycle{'s' if len(cycles) != 1 else ''} " \
                 f"({n_top} top-level, {n_nested} nested)"
    else:
        status = "no cycles"
    out(f"crate {crate.name}: {_n(len(top.children), 'module')}, "
        f"{_n(len(top.edges), 'edge')}, {status}"
        + (f" [nested: {_n(sub_mods, 'submodule')}, {_n(sub_edges, 'edge')}]"
           if nested else ""))
    for w in crate.warnings:
        out(f"  warning: {w}")
    if verbose:
        for p in sorted(levels):
            lv = levels[p]
            if not lv.edges:
                continue
            where = "top-level modules" if not p else f"children of {'::'.join(p)}"
            out(f"  edges among {where}:")
            width = max(len(_qual(p, a)) + len(_qual(p, b)) + 4 for a, b in lv.edges)
            for (a, b), info in sorted(lv.edges.items()):
                f, line, _, via = info.best()
                n = len(info.examples)
                tag = ", test code only" if info.test_only else ""
                arrow = f"{_qual(p, a)} -> {_qual(p, b)}"
                out(f"    {arrow:<{width}}  {rel(f)}:{line}  names {via}"
                    f"  ({n} reference{'s' if n != 1 else ''}{tag})")
    for lv, comp in cycles:
        members = set(comp)
        where = "top-level modules" if not lv.parent else \
            f"submodules of {'::'.join(lv.parent)}"
        out(f"  CYCLE among {where} of crate {crate.name}: "
            + ", ".join(_qual(lv.parent, c) for c in comp))
        inner = sorted((e, i) for e, i in lv.edges.items()
                       if e[0] in members and e[1] in members)
        width = max(len(_qual(lv.parent, a)) + len(_qual(lv.parent, b)) + 4
                    for (a, b), _ in inner)
        for (a, b), info in inner:
            f, line, _, via = info.best()
            tag = "  (test code only)" if info.test_only else ""
            arrow = f"{_qual(lv.parent, a)} -> {_qual(lv.parent, b)}"
            out(f"    {arrow:<{width}}  {rel(f)}:{line}  names {via}{tag}")
        shown: set[tuple[str, ...]] = set()
        for start in comp:  # a shortest cycle through each member, without repeats
            cyc = shortest_cycle(start, members, lv.edges)[:-1]
            k = cyc.index(min(cyc))
            key = tuple(cyc[k:] + cyc[:k])
            if key in shown:
                continue
            shown.add(key)
            if len(shown) > MAX_EXAMPLE_CYCLES:
                out("    ...")
                break
            out("    cycle: " + " -> ".join(_qual(lv.parent, c) for c in key + key[:1]))
    return len(cycles)


def default_root() -> str:
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if os.path.isfile(os.path.join(here, "Cargo.toml")):
        return here
    return os.getcwd()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description="Fail when modules of a crate import each other in a cycle.")
    ap.add_argument("workspaces", nargs="*",
                    help="more workspace directories to check (e.g. excluded nested ones)")
    ap.add_argument("--root", default=None,
                    help="main workspace directory (default: the repository of this script)")
    ap.add_argument("--no-main", action="store_true",
                    help="check only the workspaces given as arguments")
    ap.add_argument("--no-cargo", action="store_true",
                    help="do not run `cargo metadata`; read the Cargo.toml files")
    ap.add_argument("--verbose", "-v", action="store_true", help="print every edge")
    ap.add_argument("--ignore-tests", action="store_true",
                    help="skip #[cfg(test)] modules and files named tests.rs / *_tests.rs")
    args = ap.parse_args(argv)

    root = os.path.abspath(args.root or default_root())
    cwd = os.getcwd()

    def rel(p: str) -> str:
        p = os.path.abspath(p)
        for base in (root, cwd):
            r = os.path.relpath(p, base)
            if not r.startswith(".."):
                return r
        return p

    def note(msg: str) -> None:
        print(f"note: {msg}", file=sys.stderr)

    workspaces = [] if args.no_main else [root]
    for w in args.workspaces:
        cand = w if os.path.isabs(w) else os.path.join(cwd, w)
        if not os.path.isdir(cand) and not os.path.isabs(w):
            cand = os.path.join(root, w)
        if not os.path.isdir(cand):
            print(f"error: {w}: no such directory", file=sys.stderr)
            return 2
        workspaces.append(os.path.abspath(cand))

    targets: list[Target] = []
    for ws in workspaces:
        found = None if args.no_cargo else targets_from_cargo(ws, note)
        if found is None:
            found = targets_from_manifests(ws, note)
        targets += found
    seen: set[str] = set()
    unique: list[Target] = []
    for tg in targets:
        r = os.path.realpath(tg.src)
        if r not in seen:
            seen.add(r)
            unique.append(tg)
    if not unique:
        print("error: no library or binary targets found", file=sys.stderr)
        return 2

    total = 0
    failing = []
    for tg in sorted(unique, key=lambda t: (t.name, t.src)):
        if not os.path.isfile(tg.src):
            note(f"crate {tg.name}: root file {rel(tg.src)} is missing; skipped")
            continue
        crate = load_crate(tg.name, tg.src, args.ignore_tests, rel)
        n = check_crate(crate, args.verbose, rel, print)
        total += n
        if n:
            failing.append(crate.name)
    if total:
        print(f"FAILED: {total} module cycle{'s' if total != 1 else ''} in "
              f"{len(failing)} crate{'s' if len(failing) != 1 else ''} ({', '.join(failing)})")
        return 1
    print("OK: no module cycles")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except BrokenPipeError:  # `... | head`
        sys.exit(1)
