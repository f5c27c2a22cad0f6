"""postflight's GTSP solver against OR-Tools and PyVRP on the same instances
at the same time limit.

Reads the JSON lines of `cargo bench --bench gtsp` (postflight's runs) and the
instances that bench exported (`n`, 0-based `sets`, row-major `cost`), solves
each instance with

- OR-Tools routing: one vehicle, one disjunction per set (exactly one
  vertex of each set is visited), guided local search;
- PyVRP: one vehicle, one required, mutually exclusive client group per set;

and prints a Markdown table of mean cost, mean gap to the best known and
time for all three. Every tour is checked (one vertex per set) and its cost
recomputed from the matrix, whoever produced it.

Both libraries need a depot, which a GTSP does not have: the depot is a
vertex of the smallest set, and each of that set's vertices is tried as the
depot in turn with an equal share of the time limit.

    python compare.py --postflight runs.jsonl --instances DIR \\
        --best 89pcb442=21657 ... [--seeds 3]
"""

import argparse
import json
import statistics
import sys
import time
from pathlib import Path


def tour_cost(inst, tour):
    n, cost = inst["n"], inst["cost"]
    return sum(cost[a * n + b] for a, b in zip(tour, tour[1:] + tour[:1]))


def check_tour(inst, tour):
    set_of = {v: s for s, vs in enumerate(inst["sets"]) for v in vs}
    seen = sorted(set_of[v] for v in tour)
    if seen != list(range(len(inst["sets"]))):
        raise SystemExit(f"{inst['name']}: a tour does not visit every set exactly once")


def depot_choices(inst):
    """The smallest set, whose vertices take turns as the depot."""
    return min(inst["sets"], key=len)


def ortools_solve(inst, seconds, seed):
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    best = None
    depots = depot_choices(inst)
    for depot in depots:
        # The model's nodes: the depot, then every vertex of the other sets.
        others = [v for s in inst["sets"] if depot not in s for v in s]
        nodes = [depot] + others
        n = inst["n"]
        matrix = [[inst["cost"][a * n + b] for b in nodes] for a in nodes]
        manager = pywrapcp.RoutingIndexManager(len(nodes), 1, 0)
        routing = pywrapcp.RoutingModel(manager)
        transit = routing.RegisterTransitMatrix(matrix)
        routing.SetArcCostEvaluatorOfAllVehicles(transit)
        where = {v: i for i, v in enumerate(nodes)}
        for s in inst["sets"]:
            if depot not in s:
                routing.AddDisjunction([manager.NodeToIndex(where[v]) for v in s])
        params = pywrapcp.DefaultRoutingSearchParameters()
        params.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PATH_CHEAPEST_ARC
        params.local_search_metaheuristic = (
            routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
        )
        params.time_limit.FromMilliseconds(int(1000 * seconds / len(depots)))
        solution = routing.SolveWithParameters(params)
        if solution is None:
            continue
        tour, index = [], routing.Start(0)
        while not routing.IsEnd(index):
            tour.append(nodes[manager.IndexToNode(index)])
            index = solution.Value(routing.NextVar(index))
        cost = tour_cost(inst, tour)
        if best is None or cost < best[0]:
            best = (cost, tour)
    return best


def pyvrp_solve(inst, seconds, seed):
    from pyvrp import Model
    from pyvrp.stop import MaxRuntime

    best = None
    depots = depot_choices(inst)
    for depot in depots:
        others = [v for s in inst["sets"] if depot not in s for v in s]
        nodes = [depot] + others
        m = Model()
        locations = [m.add_location(0, 0) for _ in nodes]
        m.add_depot(locations[0])
        m.add_vehicle_type(num_available=1)
        where = {v: i for i, v in enumerate(nodes)}
        for s in inst["sets"]:
            if depot in s:
                continue
            group = m.add_client_group(required=True)
            for v in s:
                m.add_client(locations[where[v]], required=False, group=group)
        n = inst["n"]
        for i, a in enumerate(nodes):
            for j, b in enumerate(nodes):
                if i != j:
                    m.add_edge(locations[i], locations[j], inst["cost"][a * n + b])
        result = m.solve(stop=MaxRuntime(seconds / len(depots)), seed=seed, display=False)
        if not result.is_feasible():
            continue
        routes = result.best.routes()
        # A client activity's idx counts clients in the order they were added.
        visits = [others[a.idx] for a in routes[0] if a.is_client()] if routes else []
        tour = [depot] + visits
        cost = tour_cost(inst, tour)
        if best is None or cost < best[0]:
            best = (cost, tour)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--postflight", type=Path, required=True)
    ap.add_argument("--instances", type=Path, required=True)
    ap.add_argument("--best", nargs="+", required=True, help="NAME=COST")
    ap.add_argument("--seeds", type=int, default=3, help="runs of each library")
    ap.add_argument("--out", type=Path, help="all runs as JSON lines")
    args = ap.parse_args()
    best_known = {k: int(v) for k, v in (b.split("=") for b in args.best)}

    runs = [json.loads(line) for line in args.postflight.read_text().splitlines() if line]
    names = list(dict.fromkeys(r["instance"] for r in runs))
    for name in names:
        inst = json.loads((args.instances / f"{name}.json").read_text())
        seconds = next(r["time_limit_s"] for r in runs if r["instance"] == name)
        for solver, solve in [("OR-Tools", ortools_solve), ("PyVRP", pyvrp_solve)]:
            for seed in range(1, args.seeds + 1):
                started = time.monotonic()
                found = solve(inst, seconds, seed)
                elapsed = time.monotonic() - started
                if found is None:
                    runs.append({"instance": name, "solver": solver, "seed": seed,
                                 "time_limit_s": seconds, "cost": None, "time_s": elapsed})
                    continue
                check_tour(inst, found[1])
                runs.append({"instance": name, "solver": solver, "seed": seed,
                             "time_limit_s": seconds, "cost": found[0], "time_s": elapsed})
                print(f"{name} {solver} seed {seed}: {found[0]} in {elapsed:.1f} s", file=sys.stderr)

    if args.out:
        args.out.write_text("".join(json.dumps(r) + "\n" for r in runs))
    print("| instance | best known | limit | solver | runs | mean cost | mean gap | best | mean time |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in names:
        best = best_known.get(name)
        for solver in ["postflight", "OR-Tools", "PyVRP"]:
            mine = [r for r in runs if r["instance"] == name and r["solver"] == solver]
            costs = [r["cost"] for r in mine if r["cost"] is not None]
            if not costs:
                print(f"| {name} | {best} | | {solver} | {len(mine)} | no tour | | | |")
                continue
            mean = statistics.mean(costs)
            gap = f"{100 * (mean - best) / best:.3f}%" if best else ""
            limit = mine[0]["time_limit_s"]
            secs = statistics.mean(r["time_s"] for r in mine)
            failed = len(mine) - len(costs)
            runs_text = f"{len(mine)}" + (f" ({failed} no tour)" if failed else "")
            print(f"| {name} | {best} | {limit:g} s | {solver} | {runs_text} | {mean:.1f} | {gap} | {min(costs)} | {secs:.1f} s |")


if __name__ == "__main__":
    main()
