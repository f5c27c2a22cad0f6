"""Turn a TSPLIB EUC_2D instance into its GTSPLIB counterpart.

Fischetti, Salazar-Gonzalez and Toth (1997) built GTSPLIB by clustering
TSPLIB instances: m = ceil(n / 5) centres chosen as far apart as possible
(farthest-first from vertex 1), every vertex joining its nearest centre.
`--check` rebuilds a shipped GTSPLIB instance from its own coordinates and
fails unless the sets come out identical, so the procedure is the published
one, not a look-alike.

    python gtsplib.py rat783.tsp 157rat783.gtsp
    python gtsplib.py --check 39rat195.gtsp
"""

import math
import sys


def read_coords(path):
    coords, in_section = [], False
    for line in open(path):
        word = line.strip()
        if word.startswith("NODE_COORD_SECTION"):
            in_section = True
        elif in_section and word and word[0].isdigit():
            _, x, y = word.split()[:3]
            coords.append((float(x), float(y)))
        elif in_section and word:
            in_section = False
    return coords


def read_sets(path):
    tokens, in_section = [], False
    for line in open(path):
        word = line.strip()
        if word.startswith("GTSP_SET_SECTION"):
            in_section = True
        elif in_section and word and word != "EOF":
            tokens += [int(t) for t in word.split()]
    sets, current, expect_id = [], [], True
    for t in tokens:
        if expect_id:
            expect_id = False
        elif t == -1:
            sets.append(current)
            current, expect_id = [], True
        else:
            current.append(t)
    return sets


def nint_distance(a, b):
    return math.floor(math.hypot(a[0] - b[0], a[1] - b[1]) + 0.5)


def cluster(coords):
    n = len(coords)
    m = math.ceil(n / 5)
    centres = [0]
    nearest = [nint_distance(coords[v], coords[0]) for v in range(n)]
    while len(centres) < m:
        far = max(range(n), key=lambda v: (nearest[v], -v))
        centres.append(far)
        for v in range(n):
            nearest[v] = min(nearest[v], nint_distance(coords[v], coords[far]))
    sets = [[] for _ in centres]
    for v in range(n):
        k = min(range(m), key=lambda k: (nint_distance(coords[v], coords[centres[k]]), k))
        sets[k].append(v + 1)
    return sets


def write(path, name, comment, coords, sets):
    with open(path, "w") as f:
        f.write(f"NAME : {name}\nCOMMENT : {comment}\nTYPE : GTSP\n")
        f.write(f"DIMENSION : {len(coords)}\nGTSP_SETS : {len(sets)}\n")
        f.write("EDGE_WEIGHT_TYPE : EUC_2D\nNODE_COORD_SECTION\n")
        for i, (x, y) in enumerate(coords, 1):
            f.write(f"{i} {x:g} {y:g}\n")
        f.write("GTSP_SET_SECTION\n")
        for i, s in enumerate(sets, 1):
            f.write(f"{i} {' '.join(map(str, s))} -1\n")
        f.write("EOF\n")


def main(argv):
    if argv[:1] == ["--check"]:
        path = argv[1]
        shipped = sorted(sorted(s) for s in read_sets(path))
        rebuilt = sorted(sorted(s) for s in cluster(read_coords(path)))
        if shipped != rebuilt:
            sys.exit(f"{path}: clustering does not reproduce the shipped sets")
        print(f"{path}: {len(shipped)} sets reproduced exactly")
        return
    source, target = argv
    coords = read_coords(source)
    sets = cluster(coords)
    stem = source.rsplit("/", 1)[-1].removesuffix(".tsp")
    write(target, f"{len(sets)}{stem}", "GTSPLIB clustering of TSPLIB " + stem, coords, sets)
    print(f"{target}: {len(coords)} vertices, {len(sets)} sets")


if __name__ == "__main__":
    main(sys.argv[1:])
