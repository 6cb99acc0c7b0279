#!/usr/bin/env python3
"""A copy of a UWNR safetensors file with fields of its config changed (for ablations).

Usage: python3 tools/weights_variant.py IN.safetensors OUT.safetensors FIELD=VALUE...
VALUE is JSON (false, 32, "water"). The tensors are copied byte for byte; only the
`uwnr.config` metadata changes, and `uwnr.source` records the change. `uwnr info --weights OUT`
checks the result. docs/RESULTS.md's detail-retention lever used
`python3 tools/weights_variant.py assets/model/uwnr-default.safetensors v5-nodetail.safetensors
detail_retention=false`. Standard library only.
"""
import json
import os
import struct
import sys


def main(argv):
    if len(argv) < 4:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    src, dst, changes = argv[1], argv[2], argv[3:]
    data = open(src, "rb").read()
    if len(data) < 8:
        print(f"error: {src}: too short for a safetensors file", file=sys.stderr)
        return 1
    (n,) = struct.unpack("<Q", data[:8])
    try:
        header = json.loads(data[8 : 8 + n])
        meta = header["__metadata__"]
        config = json.loads(meta["uwnr.config"])
    except (ValueError, KeyError) as e:
        print(f"error: {src}: no uwnr config in its metadata ({e})", file=sys.stderr)
        return 1
    for change in changes:
        field, sep, value = change.partition("=")
        if not sep or field not in config and field not in ("detail_retention", "anchor"):
            print(f"error: {change}: expected FIELD=VALUE with a config field", file=sys.stderr)
            return 2
        try:
            config[field] = json.loads(value)
        except ValueError:
            print(f"error: {change}: VALUE is JSON (false, 32, \"water\")", file=sys.stderr)
            return 2
    meta["uwnr.config"] = json.dumps(config, separators=(",", ":"))
    meta["uwnr.source"] = meta.get("uwnr.source", "") + " -- variant: " + ", ".join(changes)
    new = json.dumps(header, separators=(",", ":")).encode()
    new += b" " * (-len(new) % 8)
    tmp = dst + ".tmp"
    with open(tmp, "wb") as f:
        f.write(struct.pack("<Q", len(new)) + new + data[8 + n :])
    os.replace(tmp, dst)
    print(f"{dst}: {meta['uwnr.config']}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
