"""The TypeScript client material of openapi/clients/typescript, without node or a network.

``.ci/clients.sh`` installs, generates, type-checks and runs it; here: its versions are pinned, in
package.json and in the committed lock file alike, and the types come from the committed spec.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
TS = ROOT / "openapi" / "clients" / "typescript"
EXACT = re.compile(r"^\d+\.\d+\.\d+$")


def _json(name: str) -> dict[str, Any]:
    return json.loads((TS / name).read_text(encoding="utf-8"))


def test_every_dependency_is_pinned_and_locked() -> None:
    package, lock = _json("package.json"), _json("package-lock.json")
    wanted = {**package["dependencies"], **package["devDependencies"]}
    assert {"openapi-typescript", "openapi-fetch", "typescript"} <= set(wanted)
    for name, version in wanted.items():
        assert EXACT.match(version), f"{name} {version} is a range, not a pinned version"
        assert lock["packages"][f"node_modules/{name}"]["version"] == version, name
    root = lock["packages"][""]
    assert {**root["dependencies"], **root["devDependencies"]} == wanted


def test_the_scripts_generate_from_the_committed_spec() -> None:
    scripts = _json("package.json")["scripts"]
    assert "../../openapi.json" in scripts["generate"]
    assert scripts["typecheck"] == "tsc --noEmit"
    assert _json("tsconfig.json")["compilerOptions"]["strict"] is True
