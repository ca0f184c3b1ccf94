#!/usr/bin/env python3
"""Fails when a file includes a layer above its own (docs/DESIGN.md, "Layers"), or a layer its
own may not reach past the ones in between.

Layers, lowest first; siblings (client and simulation; gateway and api) may not include each other:
    common < codec < transport < session < profile < client | simulation < devices < gateway | api < app
Skips: app/ (the CLI, which parses and prints only) includes nothing from session/ or transport/;
it opens links, traces frames and serves simulators through client/, simulation/, devices/ or
the public API, so no wire detail is handled in the CLI.
Run: layer_includes_test.py SRC_DIR  (prints every offending include with file and line).
"""
import pathlib
import re
import sys

RANK = {"common": 0, "codec": 1, "transport": 2, "session": 3, "profile": 4,
        "client": 5, "simulation": 5, "devices": 6, "gateway": 7, "api": 7, "app": 8}
# Layers a layer must not include although they are below it, and why.
SKIPPED = {"app": {"session": "reach it through client/, simulation/ or the public API",
                   "transport": "reach it through client/, simulation/ or the public API"}}
INCLUDE = re.compile(r'^\s*#\s*include\s+"([a-z_]+)/')


def violations(src: pathlib.Path):
    for path in sorted(src.rglob("*")):
        if path.suffix not in (".hpp", ".cpp", ".h") or not path.is_file():
            continue
        layer = path.relative_to(src).parts[0]
        if layer not in RANK:
            yield f"{path}: folder '{layer}' is not a known layer; add it to RANK in {__file__}"
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            match = INCLUDE.match(line)
            if not match or match.group(1) not in RANK:
                continue
            target = match.group(1)
            if target != layer and RANK[target] >= RANK[layer]:
                yield f"{path}:{number}: layer '{layer}' includes '{target}', which is not below it"
            elif target in SKIPPED.get(layer, {}):
                yield f"{path}:{number}: layer '{layer}' includes '{target}', which it must skip: {SKIPPED[layer][target]}"


def main() -> int:
    if len(sys.argv) != 2:
        print("usage: layer_includes_test.py SRC_DIR", file=sys.stderr)
        return 2
    src = pathlib.Path(sys.argv[1])
    files = [p for p in src.rglob("*.[ch]pp")]
    if not files:
        print(f"no sources under {src}", file=sys.stderr)
        return 2
    found = list(violations(src))
    for line in found:
        print(line)
    print(f"checked {len(files)} files: {len(found)} includes against the layer order")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
