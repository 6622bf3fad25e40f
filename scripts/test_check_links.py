#!/usr/bin/env python3
"""Self-test of check_links.py on small trees it must pass and fail."""

import subprocess
import sys
import tempfile
from pathlib import Path

SCRIPT = Path(__file__).with_name("check_links.py")
MODEL = "# Model\n\n## 1. Kinematics\n\n### 1.2 Errors\n\n## 4. Time\n"


def run(files: dict) -> int:
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        (root / "docs" / "guide").mkdir(parents=True)
        (root / "host").mkdir()
        (root / "docs" / "model.md").write_text(MODEL)
        for name, text in files.items():
            (root / name).write_text(text)
        return subprocess.run([sys.executable, str(SCRIPT), str(root)],
                              capture_output=True).returncode


def main():
    good = {
        "README.md": "[guide](docs/guide/a.md#first-steps), docs/model.md §1.2, `host/`, "
                     "paper §9.9, [web](https://example.org)\n```\n[x](nowhere.md)\n```\n",
        "docs/guide/a.md": "# A\n\n## First steps\n\n[model](../model.md#4-time) §4\n",
    }
    assert run(good) == 0, "a good tree must pass"
    for name, text in [
        ("README.md", "[missing](docs/none.md)\n"),
        ("README.md", "[anchor](docs/model.md#no-such-heading)\n"),
        ("README.md", "see docs/model.md §7.1\n"),
        ("README.md", "code in `host/nothing/here.rs`\n"),
        ("docs/guide/a.md", "[self](#nowhere)\n"),
    ]:
        assert run({**good, name: text}) == 1, f"must fail: {name}: {text!r}"
    print("check_links.py: 6 trees checked")


if __name__ == "__main__":
    main()
