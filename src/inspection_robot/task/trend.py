"""Meters drifting toward their alarm band: a warning before the alarm.

A meter's last readings (time, value) are fitted with a straight line (least squares over at most
``window`` points); when the line, continued from the newest reading, crosses the band's upper
(rising) or lower (falling) limit within ``horizon_days``, the newest reading is marked ``trend``
(an alarm state below ``alarm`` and ``check``). A value already outside the band is an alarm, not a
trend; fewer than ``min_points`` readings, or readings spanning less than ``min_span_s``, say
nothing. Pure module: task/patrol.py gives it the store's history of the meter.
"""
from collections import namedtuple

DAY_S = 86400.0

TrendConfig = namedtuple("TrendConfig", "window min_points horizon_days min_span_s")
DEFAULT_TREND = TrendConfig(window=10, min_points=4, horizon_days=7.0, min_span_s=600.0)


def fit_line(points):
    """(slope per second, value at the newest time) of the least-squares line through [(t, v)]."""
    n = float(len(points))
    mean_t = sum(t for t, _v in points) / n
    mean_v = sum(v for _t, v in points) / n
    var_t = sum((t - mean_t) ** 2 for t, _v in points)
    if var_t <= 0.0:
        return 0.0, mean_v
    slope = sum((t - mean_t) * (v - mean_v) for t, v in points) / var_t
    newest = max(t for t, _v in points)
    return slope, mean_v + slope * (newest - mean_t)


def trend_warning(points, band, config=DEFAULT_TREND):
    """None, or {"limit": "high"|"low", "days": days until the line reaches it, "slope_per_day"} for
    the meter's readings ``points`` [(unix s, value)] (any order) against ``band`` [low, high]."""
    if band is None:
        return None
    points = sorted(points)[-config.window:]
    if len(points) < config.min_points or points[-1][0] - points[0][0] < config.min_span_s:
        return None
    low, high = band
    newest = points[-1][1]
    if not low <= newest <= high:
        return None   # outside already: an alarm, not a trend
    slope, now_value = fit_line(points)
    if slope > 0:
        limit, gap = "high", high - now_value
    elif slope < 0:
        limit, gap = "low", low - now_value
    else:
        return None
    days = gap / slope / DAY_S
    if not 0.0 <= days <= config.horizon_days:
        return None
    return {"limit": limit, "days": round(days, 2), "slope_per_day": slope * DAY_S}


def trend_text(warning, unit):
    """The reading's reason for a trend warning, in words."""
    return "trend: %s %.4g%s/day, reaches its %s limit in %.1f days" % (
        "rising" if warning["slope_per_day"] > 0 else "falling", abs(warning["slope_per_day"]),
        " " + unit if unit else "", warning["limit"], warning["days"])
