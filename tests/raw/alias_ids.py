"""Rename the patches of kogei chart detect's CGATS files to the layout's aliases (the
reference charts number the ColorChecker's patches 1..24).
usage: alias_ids.py LAYOUT.json DIR NAME...: DIR/NAME.cgats -> DIR/NAME_n.cgats"""
import json
import sys

alias = {p["id"]: p["alias"] for p in json.load(open(sys.argv[1]))["patches"]}
for name in sys.argv[3:]:
    out, data = [], False
    for line in open(f"{sys.argv[2]}/{name}.cgats").read().split("\n"):
        if line == "END_DATA":
            data = False
        if data and line:
            k, rest = line.split("\t", 1)
            line = alias[k] + "\t" + rest
        if line == "BEGIN_DATA":
            data = True
        out.append(line)
    open(f"{sys.argv[2]}/{name}_n.cgats", "w").write("\n".join(out))
