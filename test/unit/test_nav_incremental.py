"""Incremental virtual obstacles: costmap and planner graph after random edits equal a full rebuild."""
import numpy as np
import pytest

from inspection_robot.nav.costmap import Costmap
from inspection_robot.nav.gridmap import GridMap
from inspection_robot.nav.planner import Planner, PlanningError

RES = 0.05


def yard(rng, size_m=30.0):
    n = int(size_m / RES)
    occ = np.zeros((n, n), dtype=np.int8)
    occ[:3, :] = occ[-3:, :] = occ[:, :3] = occ[:, -3:] = 100
    for _ in range(25):
        r, c = rng.integers(10, n - 40, 2)
        h, w = rng.integers(2, 30, 2)
        occ[r:r + h, c:c + w] = 100
    return GridMap(occ, RES, (0.0, 0.0, 0.0))


def random_polyline(rng, size_m=30.0):
    count = int(rng.integers(1, 6))
    centre = rng.uniform(-2.0, size_m + 2.0, 2)  # some reach over the map edge
    points = (centre + rng.normal(0.0, 2.5, (count, 2))).tolist()
    return points, bool(count >= 3 and rng.random() < 0.5)


def top_edges(planner):
    graph = planner._top_graph.tocoo()
    return sorted(zip(graph.row.tolist(), graph.col.tolist(), graph.data.tolist()))


def assert_same_partition(a, b):
    """Component ids are arbitrary: the same cells must be free and grouped alike."""
    np.testing.assert_array_equal(a < 0, b < 0)
    pairs = np.unique(np.stack([a[a >= 0], b[b >= 0]]), axis=1)
    assert pairs.shape[1] == len(np.unique(a[a >= 0])) == len(np.unique(b[b >= 0]))


def assert_same(incremental, planner, layer, grid):
    full = Costmap(grid, robot_radius=0.45, safety_margin=0.3)
    full.set_virtual(layer)
    np.testing.assert_array_equal(incremental.virtual, full.virtual)
    np.testing.assert_array_equal(incremental.cost, full.cost)
    assert_same_partition(incremental.component_image(), full.component_image())
    rebuilt = Planner(full)
    planner.refresh()
    np.testing.assert_array_equal(planner._block_cost, rebuilt._block_cost)
    np.testing.assert_array_equal(planner._linked, rebuilt._linked)
    np.testing.assert_array_equal(np.where(planner._linked, planner._weights, 0),
                                  np.where(rebuilt._linked, rebuilt._weights, 0))
    np.testing.assert_array_equal(planner._part, rebuilt._part)
    assert top_edges(planner) == top_edges(rebuilt)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_edits_equal_a_full_rebuild(seed):
    rng = np.random.default_rng(seed)
    grid = yard(rng)
    costmap = Costmap(grid, robot_radius=0.45, safety_margin=0.3)
    planner = Planner(costmap)
    layer = {}
    for step in range(12):
        action = rng.choice(["add", "modify", "delete"]) if layer else "add"
        if action == "add":
            layer["o%d" % step] = random_polyline(rng)
        elif action == "modify":
            layer[sorted(layer)[int(rng.integers(0, len(layer)))]] = random_polyline(rng)
        else:
            del layer[sorted(layer)[int(rng.integers(0, len(layer)))]]
        polylines = [layer[k] for k in sorted(layer)]
        costmap.set_virtual(polylines)
        assert_same(costmap, planner, polylines, grid)


def test_edit_touches_only_its_window_and_plans_follow_it():
    grid = yard(np.random.default_rng(4))
    costmap = Costmap(grid, robot_radius=0.45, safety_margin=0.3)
    planner = Planner(costmap)
    before = costmap.cost.copy()
    window = costmap.set_virtual([([[10.0, 10.0], [14.0, 10.0]], False)])
    changed = np.argwhere(before != costmap.cost)
    assert len(changed) > 0
    assert (changed[:, 0] >= window.r0).all() and (changed[:, 0] < window.r1).all()
    assert (changed[:, 1] >= window.c0).all() and (changed[:, 1] < window.c1).all()
    assert window.r1 - window.r0 < 60 and window.c1 - window.c0 < 140  # 4 m wall + inflation, not the map
    assert costmap.set_virtual([([[10.0, 10.0], [14.0, 10.0]], False)]) is None  # same layer: no work
    plan = planner.plan((12.0, 8.0), (12.0, 12.0))
    assert plan.length > 4.0  # around the new wall, not through it


def test_walls_that_split_and_join_free_space_across_label_blocks():
    """A wall across the yard (over several labelling blocks) splits it in two; opening a gate joins it."""
    grid = yard(np.random.default_rng(5), size_m=40.0)
    costmap = Costmap(grid, robot_radius=0.45, safety_margin=0.3)
    planner = Planner(costmap)
    left, right = grid.world_to_cell(5.0, 20.0), grid.world_to_cell(35.0, 20.0)
    costmap.set_virtual([])
    wall = ([[20.0, -1.0], [20.0, 41.0]], False)
    with_gate = [([[20.0, -1.0], [20.0, 18.0]], False), ([[20.0, 22.0], [20.0, 41.0]], False)]
    edits = [[wall], with_gate, [wall], [], [wall, ([[-1.0, 30.0], [41.0, 30.0]], False)], with_gate]
    split = []
    for layer in edits:
        costmap.set_virtual(layer)
        assert_same(costmap, planner, layer, grid)
        split.append(costmap.free(*left) and costmap.free(*right) and not costmap.connected(left, right))
    assert split == [True, False, True, False, True, False]
    with pytest.raises(PlanningError, match="not reachable"):
        costmap.set_virtual([wall])
        planner.plan((5.0, 20.0), (35.0, 20.0))


@pytest.mark.parametrize("seed", [5, 6])
def test_a_layer_given_as_cells_equals_the_same_layer_given_as_polylines(seed):
    """task_manager feeds move_base's published virtual cells (virtual_obstacle_map) to its costmap:
    the inflated cost and the free-space partition equal move_base's own from the polylines."""
    rng = np.random.default_rng(seed)
    grid = yard(rng)
    from_cells = Costmap(grid, robot_radius=0.45, safety_margin=0.3)
    layer = []
    for _step in range(6):
        if layer and rng.random() < 0.3:
            layer.pop(int(rng.integers(0, len(layer))))
        else:
            layer.append(random_polyline(rng))
        reference = Costmap(grid, robot_radius=0.45, safety_margin=0.3)
        reference.set_virtual(layer)
        from_cells.set_virtual_cells(reference.virtual.copy())
        np.testing.assert_array_equal(from_cells.cost, reference.cost)
        assert_same_partition(from_cells.component_image(), reference.component_image())
    assert from_cells.set_virtual_cells(from_cells.virtual.copy()) is None   # unchanged: no work
    with pytest.raises(ValueError, match="virtual layer of shape"):
        from_cells.set_virtual_cells(np.zeros((3, 3), dtype=bool))
