"""What a backend sees of task_manager's rows, status and answers: one path form, every unit.

The store keeps the absolute paths the robot's nodes work with (find_scale opens the preset
directory, read_scale names the pictures it wrote). Everything that leaves task_manager for a
client (task_status, task_action, query_results, review_queue, review, the reports' rows) names a
robot file relative to the data root, as file_control does (``presets/p1/20260101_120000``,
``pictures/p1/..._read_00.jpg``), so a path from one answer is the path of the next request.
A file outside the data root keeps its absolute path. Rows of tasks stored before thermal
readings carried their unit get ``C``. Every row carries its value as text rounded to the meter's
resolution (``display``, ``review_display``: task.display), so no client rounds on its own.
"""
from inspection_robot.files import root_relative
from inspection_robot.task.display import row_display
from inspection_robot.task.states import target_unit

PATH_COLUMNS = ("preset", "picture", "source_picture")   # reading columns naming a robot file


def client_row(row, data_root):
    """A reading row (store.READING_COLUMNS) as a client sees it."""
    out = dict(row)
    for column in PATH_COLUMNS:
        if out.get(column):
            out[column] = root_relative(out[column], data_root)
    if out.get("kind") and not out.get("unit"):
        out["unit"] = target_unit(out["kind"])
    out.update(row_display(out))
    return out


def client_result(result, data_root):
    """task_status / task_action ``last_result`` (patrol.result_summary) as a client sees it."""
    if not result:
        return result
    return dict(result, preset=root_relative(result["preset"], data_root))


def client_progress(progress, data_root):
    """task_status or task_action feedback fields with their ``last_result`` as a client sees it."""
    if "last_result" not in progress:
        return progress
    return dict(progress, last_result=client_result(progress["last_result"], data_root))
