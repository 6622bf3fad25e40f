#!/usr/bin/env python3
"""Every relative link and § reference in README.md and docs/ resolves.

usage: check_links.py [ROOT]

Checks, in README.md and every docs/**/*.md under ROOT:
* a relative markdown link `[text](path)` or `[text](path#anchor)` names an
  existing file or folder (relative to the markdown file), and its anchor a
  heading of the target (GitHub's slugs); `[text](#anchor)` a heading of
  the same file;
* a `§` reference — `model.md §4.6`, `docs/model.md §4.6` or a bare `§4.6`
  (the reference's sections; `paper §3.1` is the paper's and is skipped) —
  names a numbered heading (`## 4.` / `### 4.6 …`) of docs/model.md;
* a repository path in backticks (`host/…`, `docs/…`, …) exists.
External links (http, https, mailto) and fenced code blocks are not checked.
Prints each broken reference as FILE:LINE and exits 1 when there is any.
"""

import re
import sys
from pathlib import Path

LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
SECTION = re.compile(r"(?:(?:docs/)?model\.md\s+)?§\s?(\d+(?:\.\d+)*)")
TICKED = re.compile(r"`([^`\s]+)`")
TOP = ("host/", "hil-sim/", "firmware/", "protocol/", "tests/", "docs/", "scripts/",
       "peers/", ".ci/", "controller-wire/")


def slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    s = heading.strip().lower()
    s = re.sub(r"[^\w\- ]", "", s)
    return s.replace(" ", "-")


def headings(path: Path):
    out, fence = [], False
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            fence = not fence
        elif not fence and line.startswith("#"):
            out.append(line.lstrip("#").strip())
    return out


def model_sections(model: Path):
    nums = set()
    if model.is_file():
        for h in headings(model):
            m = re.match(r"(\d+(?:\.\d+)*)\.?\s", h + " ")
            if m:
                nums.add(m.group(1))
    return nums


def is_path_like(text: str) -> bool:
    if not text.startswith(TOP) or any(c in text for c in "<>*{}$|…"):
        return False
    return not re.search(r"[A-Z]{3,}", text)  # placeholders such as NAME, DIR


def check_file(md: Path, root: Path, sections, errors):
    fence = False
    for n, line in enumerate(md.read_text(encoding="utf-8").splitlines(), 1):
        if line.startswith("```"):
            fence = not fence
            continue
        if fence:
            continue
        where = f"{md.relative_to(root)}:{n}"
        for target in LINK.findall(line):
            if re.match(r"^[a-z]+:", target):
                continue
            path, _, anchor = target.partition("#")
            dest = md if not path else (md.parent / path)
            if not dest.exists():
                errors.append(f"{where}: link to a missing file: {target}")
                continue
            if anchor and dest.is_file() and dest.suffix == ".md":
                if anchor not in {slug(h) for h in headings(dest)}:
                    errors.append(f"{where}: no heading #{anchor} in {path or md.name}")
        for m in SECTION.finditer(line):
            if re.search(r"(paper|Paper|paper's)\s*$", line[: m.start()]):
                continue  # the paper's sections, not the reference's
            if m.group(1) not in sections:
                errors.append(f"{where}: no section §{m.group(1)} in docs/model.md")
        for text in TICKED.findall(line):
            if is_path_like(text) and not (root / text.rstrip("/")).exists():
                errors.append(f"{where}: no such path: {text}")


def main():
    root = Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
    sections = model_sections(root / "docs" / "model.md")
    files = [root / "README.md"] + sorted((root / "docs").rglob("*.md"))
    errors = []
    for md in files:
        if md.is_file():
            check_file(md, root, sections, errors)
    for e in errors:
        print(e)
    print(f"{len(files)} files, {len(errors)} broken references")
    sys.exit(1 if errors else 0)


if __name__ == "__main__":
    main()
