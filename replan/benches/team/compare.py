#!/usr/bin/env python3
"""A team's follow-up flight, postflight's split against OR-Tools' vehicle
routing at equal time.

The instance is the team plan's own: home and the waypoints postflight
chose (replan.json with `drones` > 1). OR-Tools routes the same waypoints
with as many vehicles from home, minimising the longest route (a global
span cost on the time dimension), with the time limit postflight's replan
stage took in all. Both missions are costed alike: straight legs at the
plan's speed plus its hover at each waypoint, each drone's sorties flown
one after the other.

Run: compare.py REPLAN_JSON [--name NAME] [--limit-s S] [--coverage
COVERAGE_VIEWPOINTS_JSON]; prints one JSON line.
"""

import argparse
import json
import math
import sys

from ortools.constraint_solver import pywrapcp, routing_enums_pb2


def dist(a, b):
    return math.dist(a, b)


def mission_of(routes, home, speed, hover):
    """The longest drone time: each route (a list of sorties, each a list
    of points) flown home to home, sortie after sortie."""
    longest = 0.0
    for sorties in routes:
        total = 0.0
        for points in sorties:
            path = [home] + points + [home]
            total += sum(dist(p, q) for p, q in zip(path, path[1:])) / speed + hover * len(points)
        longest = max(longest, total)
    return longest


def postflight_routes(plan):
    drones = max(s["drone"] for s in plan["sorties"]) + 1
    routes = [[] for _ in range(drones)]
    for s in plan["sorties"]:
        routes[s["drone"]].append([(w["x"], w["y"], w["z"]) for w in s["waypoints"]])
    return routes


def ortools_routes(home, points, vehicles, speed, hover, limit_s):
    nodes = [home] + points
    # Milliseconds: OR-Tools costs are integers.
    def cost(i, j):
        travel = dist(nodes[i], nodes[j]) / speed
        return int(round(1000 * (travel + (hover if j != 0 else 0.0))))

    manager = pywrapcp.RoutingIndexManager(len(nodes), vehicles, 0)
    routing = pywrapcp.RoutingModel(manager)
    transit = routing.RegisterTransitCallback(
        lambda a, b: cost(manager.IndexToNode(a), manager.IndexToNode(b)))
    routing.SetArcCostEvaluatorOfAllVehicles(transit)
    routing.AddDimension(transit, 0, 10**12, True, "time")
    routing.GetDimensionOrDie("time").SetGlobalSpanCostCoefficient(100)
    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PATH_CHEAPEST_ARC
    params.local_search_metaheuristic = routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
    params.time_limit.FromMilliseconds(max(1, int(limit_s * 1000)))
    solution = routing.SolveWithParameters(params)
    if solution is None:
        sys.exit("compare.py: OR-Tools found no solution in the time limit")
    routes = []
    for v in range(vehicles):
        index, route = routing.Start(v), []
        while not routing.IsEnd(index):
            node = manager.IndexToNode(index)
            if node != 0:
                route.append(nodes[node])
            index = solution.Value(routing.NextVar(index))
        routes.append([route] if route else [])
    return routes


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("replan")
    parser.add_argument("--name", default="")
    parser.add_argument("--limit-s", type=float, default=None)
    parser.add_argument("--coverage", help="coverage-viewpoints.json of the plan's routes, targets the plan's")
    args = parser.parse_args()
    plan = json.load(open(args.replan))
    if len(plan.get("drones", [])) < 2:
        sys.exit("compare.py: the plan is not a team's (replan --drones N, N > 1)")
    home = tuple(plan["home"])
    speed, hover = plan["speed_m_s"], plan["hover_s"]
    ours = postflight_routes(plan)
    points = [p for sorties in ours for sortie in sorties for p in sortie]
    limit = args.limit_s if args.limit_s is not None else plan["seconds"]
    theirs = ortools_routes(home, points, len(ours), speed, hover, limit)
    one = mission_of([[points]], home, speed, hover)
    a, b = mission_of(ours, home, speed, hover), mission_of(theirs, home, speed, hover)
    judged = json.load(open(args.coverage)) if args.coverage else {}
    print(json.dumps({
        "instance": args.name, "gap_voxels": plan["gap_voxels"],
        "planned_gap_voxels": plan["planned_gap_voxels"],
        "planned_inspected_by_the_team": judged.get("inspected_voxels"),
        "waypoints": len(points), "drones": len(ours),
        "time_limit_s": round(limit, 2),
        "postflight_mission_s": round(a, 1), "ortools_mission_s": round(b, 1),
        "postflight_over_ortools": round(a / b, 3),
        "one_drone_tour_s": round(one, 1),
        "postflight_flown_mission_s": round(plan["mission_time_s"], 1),
    }))


if __name__ == "__main__":
    main()
