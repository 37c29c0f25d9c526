"""Reads bench/model_catalog_sets.sh's output for the studies' summarize.py scripts:
lines `SCENE VIEW KIND LABEL :: TEXT` (other lines, such as a skipped scene, are ignored)."""
import re


def read_runs(path, parse):
    """(order, rows): the ray-set keys (scene, view, kind) in file order, and for each key
    {label: parse(lookup)} where lookup(pattern) is float(first group of pattern in TEXT)."""
    rows, order = {}, []
    for line in open(path):
        m = re.match(r"(\S+) (\S+) (\S+) (\S+) :: (.*)", line)
        if not m:
            continue
        key, text = m.group(1, 2, 3), m.group(5)
        if key not in rows:
            rows[key] = {}
            order.append(key)
        rows[key][m.group(4)] = parse(lambda pat, t=text: float(re.search(pat, t).group(1)), text)
    return order, rows
