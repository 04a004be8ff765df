#!/usr/bin/env python3
"""A BagIt 1.0 (RFC 8493) check of a bag written by kogei deposit, independent of
kogei's code: bagit.txt, every payload file's sha512 recomputed against
manifest-sha512.txt (paths percent-decoded, every file under data/ listed and nothing
else), tagmanifest-sha512.txt over the tag files, bag-info.txt's Payload-Oxum and
Bagging-Date, the External-Identifier lines expected, other labels expected, and the
payload compared file by file with the folders it was made from.

usage: bagit_check.py BAG [--id VALUE]... [--info 'Label: value']... [--no-label L]...
                          [--source DIR PREFIX]...
Prints "N FILES OCTETS" on success; exits 1 naming every problem."""
import datetime
import hashlib
import os
import re
import sys

problems = []


def problem(msg):
    problems.append(msg)
    print("bagit_check: " + msg, file=sys.stderr)


def sha512(path):
    h = hashlib.sha512()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def decode(path):
    # RFC 8493 2.1.3: only CR, LF and % are percent-encoded
    return re.sub(r"%(0[aAdD]|25)", lambda m: chr(int(m.group(1), 16)), path)


def read_manifest(bag, name):
    entries = {}
    with open(os.path.join(bag, name), "rb") as f:
        text = f.read().decode("utf-8")
    if not text.endswith("\n"):
        problem("%s: the last line has no line end" % name)
    for n, line in enumerate(text.split("\n")[:-1], 1):
        m = re.fullmatch(r"([0-9a-fA-F]{128})[ \t]+(.+)", line.rstrip("\r"))
        if not m:
            problem("%s: line %d: not 'SHA512 PATH': %r" % (name, n, line))
            continue
        path = decode(m.group(2))
        if path in entries:
            problem("%s: %r listed twice" % (name, path))
        entries[path] = m.group(1).lower()
    return entries


def files_under(root, prefix):
    out = {}
    for d, dirs, files in os.walk(root):
        for f in files:
            full = os.path.join(d, f)
            rel = os.path.relpath(full, root).replace(os.sep, "/")
            out[prefix + "/" + rel if prefix else rel] = full
    return out


def bag_info(bag):
    labels = []
    with open(os.path.join(bag, "bag-info.txt"), "rb") as f:
        text = f.read().decode("utf-8")
    for line in text.split("\n")[:-1]:
        if line[:1] in (" ", "\t") and labels:  # a folded value continues
            labels[-1] = (labels[-1][0], labels[-1][1] + " " + line.strip())
            continue
        m = re.fullmatch(r"([^:\s][^:]*): (.*)", line)
        if not m:
            problem("bag-info.txt: not 'Label: value': %r" % line)
            continue
        labels.append((m.group(1), m.group(2)))
    return labels


def main(argv):
    bag = argv[1]
    ids, infos, absent, sources = [], [], [], []
    i = 2
    while i < len(argv):
        if argv[i] == "--id":
            ids.append(argv[i + 1])
        elif argv[i] == "--info":
            infos.append(argv[i + 1])
        elif argv[i] == "--no-label":
            absent.append(argv[i + 1])
        elif argv[i] == "--source":
            sources.append((argv[i + 1], argv[i + 2]))
            i += 1
        else:
            sys.exit("bagit_check: unknown argument %r" % argv[i])
        i += 2

    with open(os.path.join(bag, "bagit.txt"), "rb") as f:
        bagit = f.read()
    if bagit != b"BagIt-Version: 1.0\nTag-File-Character-Encoding: UTF-8\n":
        problem("bagit.txt: %r" % bagit)

    manifest = read_manifest(bag, "manifest-sha512.txt")
    payload = files_under(os.path.join(bag, "data"), "data")
    for path in sorted(set(manifest) - set(payload)):
        problem("%s: in the manifest, not in data/" % path)
    for path in sorted(set(payload) - set(manifest)):
        problem("%s: in data/, not in the manifest" % path)
    octets = 0
    for path in sorted(set(manifest) & set(payload)):
        if sha512(payload[path]) != manifest[path]:
            problem("%s: its sha512 differs from the manifest's" % path)
        octets += os.path.getsize(payload[path])

    tags = read_manifest(bag, "tagmanifest-sha512.txt")
    for t in ("bagit.txt", "bag-info.txt", "manifest-sha512.txt"):
        if t not in tags:
            problem("tagmanifest-sha512.txt: does not list %s" % t)
        elif sha512(os.path.join(bag, t)) != tags[t]:
            problem("%s: its sha512 differs from the tag manifest's" % t)

    labels = bag_info(bag)
    values = {}
    for k, v in labels:
        values.setdefault(k.lower(), []).append(v)
    oxum = values.get("payload-oxum", [""])
    if oxum != ["%d.%d" % (octets, len(payload))]:
        problem("Payload-Oxum %s, the payload is %d octets in %d files" % (oxum, octets,
                                                                            len(payload)))
    date = values.get("bagging-date", [""])[0]
    if date != datetime.date.today().isoformat():
        problem("Bagging-Date %r, not today (YYYY-MM-DD)" % date)
    if sorted(values.get("external-identifier", [])) != sorted(ids):
        problem("External-Identifier %s, expected %s" % (values.get("external-identifier"), ids))
    for want in infos:
        k, v = want.split(": ", 1)
        if v not in values.get(k.lower(), []):
            problem("bag-info.txt: no %r (it has %s: %s)" % (want, k, values.get(k.lower())))
    for k in absent:
        if k.lower() in values:
            problem("bag-info.txt: %s present: %s" % (k, values[k.lower()]))
    if not any(v.startswith("kogei ") for v in values.get("bag-software-agent", [])):
        problem("Bag-Software-Agent: %s" % values.get("bag-software-agent"))

    for src, prefix in sources:
        for rel, full in files_under(src, prefix).items():
            if rel not in payload:
                problem("%s: not in the bag (as %s)" % (full, rel))
            elif sha512(full) != sha512(payload[rel]):
                problem("%s: differs from %s" % (rel, full))

    if problems:
        return 1
    print("%d FILES %d" % (len(payload), octets))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
