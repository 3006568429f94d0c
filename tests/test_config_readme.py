"""config/README.md's key table against the schema it documents (one source: the schema).

The schema (``workflow/schemas/config.schema.yaml``) holds every key, its
type, enum and default; the README's table is the page people read.  Each
schema key has its row, each row names schema keys, an enum's values are the
row's, and a row's default is the schema's default or, where the shipped
``config/config.yaml`` sets another value, that value.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = yaml.safe_load((ROOT / "workflow" / "schemas" / "config.schema.yaml").read_text())
CONFIG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
PAGE = ROOT / "config" / "README.md"


def leaves(schema: dict[str, Any], prefix: str = "") -> dict[str, dict[str, Any]]:
    """Every key of the schema whose value is not an object of named keys, by its dotted path."""
    out: dict[str, dict[str, Any]] = {}
    for name, sub in schema.get("properties", {}).items():
        path = f"{prefix}{name}"
        if "properties" in sub:
            out.update(leaves(sub, path + "."))
        else:
            out[path] = sub
    return out


def rows() -> list[tuple[list[str], list[str], str]]:
    """The table's rows: (keys, defaults, type cell), keys written ``a`` / ``.b`` expanded to full paths."""
    got = []
    for line in PAGE.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 4 or not cells[0].startswith("`"):
            continue
        keys: list[str] = []
        for part in cells[0].split(" / "):
            name = part.strip().strip("`")
            if not keys or "." in name.lstrip("."):
                keys.append(name)
            else:  # relative to the first key's parent: `a.b.c` / `.d` or `a.b` / `d`
                keys.append(keys[0].rsplit(".", 1)[0] + "." + name.lstrip("."))
        defaults = [d.strip() for d in cells[2].split(" / ")]
        got.append((keys, defaults if len(defaults) == len(keys) else [], cells[1]))
    return got


LEAVES = leaves(SCHEMA)
ROWS = rows()


def shipped(key: str) -> Any:
    node: Any = CONFIG
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def test_every_schema_key_has_its_row_and_every_row_names_schema_keys() -> None:
    documented = [k for keys, _, _ in ROWS for k in keys]
    assert len(documented) == len(set(documented)), "a key has two rows"
    assert set(documented) - set(LEAVES) == set(), "rows naming keys the schema lacks"
    assert set(LEAVES) - set(documented) == set(), "schema keys without a row in config/README.md"


@pytest.mark.parametrize("keys, defaults, kind", ROWS, ids=[" / ".join(r[0]) for r in ROWS])
def test_a_rows_enum_and_default_are_the_schemas(keys: list[str], defaults: list[str], kind: str) -> None:
    for i, key in enumerate(keys):
        spec = LEAVES[key]
        enum = spec.get("enum") or spec.get("items", {}).get("enum")
        if enum:
            named = set(re.findall(r"`([^`]+)`", kind))
            assert set(enum) <= named, f"{key}: the row's type lacks {sorted(set(enum) - named)}"
        if not defaults or not re.fullmatch(r"`[^`…]+`", defaults[i]):
            continue  # a default in words ("all four") or abridged ("[10, 20, …, 90]")
        written = yaml.safe_load(defaults[i].strip("`"))
        if isinstance(written, str) and re.fullmatch(r"[0-9.]+e-?[0-9]+", written):
            written = float(written)  # YAML 1.1 reads 1e-5 as a string
        value = shipped(key)
        assert written in (spec.get("default"), value), (
            f"{key}: the row's default {written!r} is neither the schema's {spec.get('default')!r} "
            f"nor config.yaml's {value!r}")
