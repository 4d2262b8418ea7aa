"""query_status -> voice_cmd: the robot's status as a VoiceCmd ``data`` list.

Elements follow the voice format of INTERFACE.md ("Voice"): ``%87%`` percent, ``(25)``
temperature, ``[48]`` number; every other element names a clip ``<name>.wav`` that robot_voice
plays. Clips used: status_report, mode_task|mode_server|mode_joy, battery_quantity,
battery_voltage, volt, battery_temperature, status_normal, and one ``alarm_<reason>`` per active
stop reason (alarm_soft_estop, alarm_hard_estop, alarm_front_collision, alarm_left_fall,
alarm_right_fall, alarm_obstacle, alarm_drive_fault) plus alarm_battery_critical,
alarm_joystick_lost when those bits are set, and charging while the battery charges.
"""
from inspection_robot.interface import (BATTERY_CHARGING, CIRCUIT_BATTERY_CRITICAL, CIRCUIT_JOY_COMM_LOST,
                                        MODE_NAMES, MODE_TASK, TEMP_BATTERY, TEMPERATURE_NOT_SAMPLED)


def status_sentence(fields, stop_reasons):
    """``fields``: control_status fields (control_status_fields); ``stop_reasons``: SafetyLatch.reasons()."""
    words = ["status_report", "mode_" + MODE_NAMES.get(fields["mode"], MODE_NAMES[MODE_TASK]),
             "battery_quantity", "%%%d%%" % fields["battery_quantity"],
             "battery_voltage", "[%d]" % int(round(fields["battery_voltage"] / 10.0)), "volt"]
    battery_temp = fields["temperature"][TEMP_BATTERY]
    if battery_temp != TEMPERATURE_NOT_SAMPLED:
        words += ["battery_temperature", "(%d)" % int(round(battery_temp / 10.0))]
    alarms = ["alarm_" + reason for reason in stop_reasons]
    if fields["circuit_status"] & CIRCUIT_BATTERY_CRITICAL:
        alarms.append("alarm_battery_critical")
    if fields["circuit_status"] & CIRCUIT_JOY_COMM_LOST:
        alarms.append("alarm_joystick_lost")
    if fields["battery_status"] & BATTERY_CHARGING:
        words.append("charging")
    return words + (alarms or ["status_normal"])
