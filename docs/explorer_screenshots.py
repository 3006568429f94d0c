#!/usr/bin/env python
"""Screenshots of the explorer for docs/design/explorer.md: docs/explorer-{map,path,q5}.png.

Usage: python docs/explorer_screenshots.py [results/explorer] [--only map|path|q5 ...]
(headless chromium, SwiftShader)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from brdfpipe.explorer.chromium import Browser

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("site", nargs="?", type=Path, default=ROOT / "results" / "explorer")
    ap.add_argument("--only", nargs="+", choices=("map", "path", "q5"), default=("map", "path", "q5"))
    args = ap.parse_args()
    site, only = args.site, set(args.only)
    out = ROOT / "docs"
    with Browser(width=1280, height=800) as b:
        b.open(site / "index.html", ready="window.explorer && (window.explorer.ready || window.explorer.error)",
               timeout=300)
        if b.evaluate("explorer.error") or b.errors:
            raise SystemExit(f"page error: {b.evaluate('explorer.error')} {b.errors}")
        # the q = 2 map: the pointer between materials
        man = b.evaluate("explorer.manifest")
        st = b.evaluate("explorer.state()")
        x, y = b.evaluate(f"explorer.mapToPage({json.dumps(st['point'])})")
        b.mouse("mouseMoved", x + 25, y - 15)
        b.evaluate("new Promise(r => requestAnimationFrame(() => r(1)))")
        if "map" in only:
            b.screenshot(out / "explorer-map.png")
        # path mode at the first rendered reference
        if man["paths"] and "path" in only:
            p = man["paths"][len(man["paths"]) // 2]
            b.evaluate(f"explorer.setPath({json.dumps(p['a'])}, {json.dumps(p['b'])}, {p['t']})")
            b.screenshot(out / "explorer-path.png")
        b.evaluate("explorer.setMode('map')")
        qs = [m["q"] for m in man["models"] if m["q"] > 2]
        if qs and "q5" in only:
            b.evaluate(f"explorer.setModel({qs[0]})")
            b.evaluate("explorer.setDims(0, 2)")
            b.screenshot(out / "explorer-q5.png")
    print("written:", sorted(p.name for p in out.glob("explorer-*.png")))


if __name__ == "__main__":
    main()
