#!/usr/bin/env python3
"""The public surface of each library crate of the workspace (issue 36).

usage: pub_surface.py [ROOT] [--list] [--check]

For each library crate (a package with src/lib.rs under host/, hil-sim/,
protocol/, firmware/), the public names: the top-level `pub` items (fn,
struct, enum, trait, const, static, type, mod) of every module that is
public from the crate's root (a chain of `pub mod`), and the names that
`pub use` re-exports there. A name is

* "root"    when the crate root (src/lib.rs) lists it: `pub use` of it or
            `pub mod` of it, each with its doc line (the entry points);
* "outside" when another package of the workspace, or the crate's own
            tests/, benches/ or examples/ (crates of their own), names it
            (word match in the .rs files);
* "unused"  otherwise: public, but neither an entry point nor used by
            another package (a candidate for `pub(crate)`).

Prints one line per crate (names, root, outside, unused) and with --list
the unused names with their file. With --check, exits 1 when any crate
has an unused name. Test code (files named *tests.rs, folders tests/,
a file's `#[cfg(test)] mod … { }` and what follows it) is left out.
"""

import re
import sys
from pathlib import Path

ITEM = re.compile(
    r"^pub\s+(?:unsafe\s+)?(?:async\s+)?(?:const\s+fn|fn|struct|enum|trait|const|static|type|mod)\s+([A-Za-z_][A-Za-z0-9_]*)"
)
USE = re.compile(r"^pub\s+use\s+(.*?);", re.S | re.M)
MOD = re.compile(r"^(pub\s+)?mod\s+([A-Za-z_][A-Za-z0-9_]*)\s*;", re.M)


TEST_MOD = re.compile(r"#\[cfg\(test\)\]\s*(pub(\(\w+\))?\s+)?mod\s+\w+\s*\{")


def code_of(path: Path) -> str:
    """A file's code before its test module."""
    text = path.read_text(encoding="utf-8", errors="replace")
    m = TEST_MOD.search(text)
    return text if m is None else text[: m.start()]


def module_file(dir_: Path, name: str) -> Path | None:
    for p in (dir_ / f"{name}.rs", dir_ / name / "mod.rs"):
        if p.is_file():
            return p
    return None


def child_dir(path: Path) -> Path:
    """Where a module file's submodules live."""
    if path.name in ("lib.rs", "mod.rs"):
        return path.parent
    return path.parent / path.stem


def public_files(lib: Path):
    """(file, public) for every module file reachable from the root."""
    out = []
    stack = [(lib, True)]
    while stack:
        path, public = stack.pop()
        out.append((path, public))
        code = code_of(path)
        for m in MOD.finditer(code):
            f = module_file(child_dir(path), m.group(2))
            if f is not None and not f.name.endswith("tests.rs"):
                stack.append((f, public and bool(m.group(1))))
    return out


def use_names(spec: str):
    """The names a `pub use` brings in (last path segment, or `as` name)."""
    spec = re.sub(r"\s+", " ", spec)
    names = []
    # expand one level of braces at a time
    def walk(s):
        s = s.strip()
        if "{" in s:
            head, _, rest = s.partition("{")
            inner = rest[: rest.rfind("}")]
            depth, cur, parts = 0, "", []
            for ch in inner:
                if ch == "," and depth == 0:
                    parts.append(cur)
                    cur = ""
                    continue
                depth += ch == "{"
                depth -= ch == "}"
                cur += ch
            parts.append(cur)
            for p in parts:
                if p.strip():
                    walk(p)
            return
        if " as " in s:
            names.append(s.split(" as ")[-1].strip())
        else:
            last = s.split("::")[-1].strip()
            if last not in ("self", "*", ""):
                names.append(last)
    walk(spec)
    return names


def crates(root: Path):
    for toml in sorted(root.glob("**/Cargo.toml")):
        if "target" in toml.parts or "boards" in toml.parts:
            continue
        lib = toml.parent / "src" / "lib.rs"
        if lib.is_file():
            m = re.search(r'^name\s*=\s*"([^"]+)"', toml.read_text(), re.M)
            yield m.group(1), toml.parent, lib


def rs_files(pkg: Path, others: set):
    for f in pkg.rglob("*.rs"):
        if "target" in f.parts:
            continue
        # a nested package's files belong to it
        if any(o != pkg and o in f.parents for o in others):
            continue
        yield f


def main():
    args = sys.argv[1:]
    root = Path(next((a for a in args if not a.startswith("--")), "."))
    listing, check = "--list" in args, "--check" in args
    all_crates = list(crates(root))
    pkgs = {d for _, d, _ in all_crates}
    # every package of the workspace that can name a crate (libraries, the cli, tests)
    users = {}
    for toml in sorted(root.glob("**/Cargo.toml")):
        if "target" in toml.parts or "boards" in toml.parts:
            continue
        if "[package]" in toml.read_text():
            users[toml.parent] = None
    pkgs_all = set(users)
    texts = {d: "\n".join(f.read_text(errors="replace") for f in rs_files(d, pkgs_all)) for d in pkgs_all}
    bad = 0
    for name, pkg, lib in all_crates:
        names = {}
        root_listed = set()
        for path, public in public_files(lib):
            if not public:
                continue
            code = code_of(path)
            for line in code.splitlines():
                m = ITEM.match(line)
                if m:
                    names.setdefault(m.group(1), path)
                    if path == lib:
                        root_listed.add(m.group(1))
            for m in USE.finditer(code):
                for n in use_names(m.group(1)):
                    names.setdefault(n, path)
                    if path == lib:
                        root_listed.add(n)
        # other packages, and this package's own tests, benches and examples
        # (each a crate of its own that uses the library's public API)
        own = "\n".join(
            f.read_text(errors="replace")
            for sub in ("tests", "benches", "examples")
            for f in (pkg / sub).rglob("*.rs")
        )
        outside_text = "\n".join(t for d, t in texts.items() if d != pkg) + own
        counts = {"root": 0, "outside": 0, "unused": 0}
        unused = []
        for n, path in sorted(names.items()):
            if n in root_listed:
                counts["root"] += 1
            elif re.search(r"\b" + re.escape(n) + r"\b", outside_text):
                counts["outside"] += 1
            else:
                counts["unused"] += 1
                unused.append((n, path))
        print(
            f"{name:22} {len(names):4} public names: {counts['root']:4} at the root, "
            f"{counts['outside']:4} used outside, {counts['unused']:4} neither"
        )
        if listing:
            for n, path in unused:
                print(f"    {n:40} {path.relative_to(root)}")
        bad += counts["unused"]
    if check and bad:
        print(f"{bad} public names are neither entry points nor used outside their crate")
        sys.exit(1)


if __name__ == "__main__":
    main()
