"""control_status assembly: the spec's bit fields and units from the latch and the chassis state."""
import math

from inspection_robot.interface import (
    BATTERY_CURRENT_UNIT_A, BATTERY_VOLTAGE_UNIT_V, LIGHT_BLUE, LIGHT_CHARGE_RELAY, LIGHT_GREEN, LIGHT_RED,
    MOTOR_COUNT, TEMPERATURE_COUNT, TEMPERATURE_NOT_SAMPLED, TEMPERATURE_UNIT_C, WHEEL_STEER, WHEEL_STEER_MODE,
    WHEEL_STRAIGHT_MODE, WHEEL_SWITCHING)

INT32_MAX = 2 ** 31 - 1


def _scaled(value, unit):
    if value is None or not math.isfinite(value):
        return None
    return max(-INT32_MAX, min(INT32_MAX, int(round(value / unit))))


def _fixed(values, length, fill):
    return (list(values) + [fill] * length)[:length]


def control_status_fields(mode, safety, state):
    """ControlStatus fields (without the header block) as a dict, from the mode, a SafetyLatch
    and a ChassisState. Temperatures not sampled (None) become -1000; battery_current > 0 = charging."""
    wheel = WHEEL_STEER_MODE if state.wheel_mode == WHEEL_STEER else WHEEL_STRAIGHT_MODE
    if state.switching:
        wheel = WHEEL_SWITCHING  # neither geometry while the wheels turn
    wheel |= (state.fault_clear & 0x18) | safety.wheel_off_bits()
    red, green, blue = state.lamps
    light = ((LIGHT_CHARGE_RELAY if state.charge_relay else 0) | (LIGHT_RED if red else 0)
             | (LIGHT_GREEN if green else 0) | (LIGHT_BLUE if blue else 0) | safety.light_bits())
    temperatures = []
    for value in _fixed(state.temperatures_c, TEMPERATURE_COUNT, None):
        scaled = _scaled(value, TEMPERATURE_UNIT_C)
        temperatures.append(TEMPERATURE_NOT_SAMPLED if scaled is None else scaled)
    return dict(
        mode=int(mode), wheel_status=wheel & 0xFF, light_status=light & 0xFF,
        stop_status=safety.stop_status() & 0xFF, circuit_status=int(state.circuit_status) & 0xFF,
        other_status=[],
        battery_voltage=_scaled(state.battery_voltage, BATTERY_VOLTAGE_UNIT_V) or 0,
        battery_current=_scaled(state.battery_current, BATTERY_CURRENT_UNIT_A) or 0,
        battery_quantity=max(0, min(100, int(state.battery_quantity))),
        battery_status=int(state.battery_status) & 0xFF,
        motor_status=[int(v) & 0xFF for v in _fixed(state.motor_status, MOTOR_COUNT, 0)],
        motor_info=[int(v) & 0xFFFFFFFF for v in _fixed(state.motor_info, MOTOR_COUNT, 0)],
        temperature=temperatures)
