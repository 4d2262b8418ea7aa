"""The simulated substation yard the cameras look at (config/sim_world.yaml), without any drawing.

Equipment are boxes on the ground (map frame, metres, yaw counter-clockwise from +x). Faces
(pointer gauges, indicator lamps, switch-position indicators) and thermal hot spots sit on one
side of an equipment box; this module turns their YAML description into 3D geometry and owns
their current values, which a simulator service changes at run time (``World.set_value``).

Side frame: ``front`` is the box's +x side (equipment frame), ``back`` -x, ``left`` +y,
``right`` -y. On a side, ``center: [u, v]`` is u metres to the right of the side's middle as seen
by a viewer facing the side from outside, v metres above the ground.
"""
import math

import numpy as np
import yaml

SIDES = ("front", "back", "left", "right")
FACE_TYPES = ("gauge", "lamp", "switch", "display")
DISPLAY_WINDOW = (0.08, 0.15, 0.92, 0.85)   # a display face's digit window: left, top, right, bottom fractions
GAUGE_STYLES = ("round_white", "round_black", "panel_arc")
LAMP_VALUES = ("on", "off")
LAMP_COLORS = ("red", "green", "yellow", "white", "blue")
SWITCH_VALUES = ("open", "closed")
ZONE_COLORS = ("red", "green", "yellow")
HOT_SPOT_RANGE_C = (-40.0, 600.0)
FACE_STANDOFF_M = 0.005  # faces sit this far in front of their side so they never z-fight with it
FOREIGN_PREFIX = "foreign/"
LIGHT_ID = "light"          # day | night: at night the camera sees by its infrared illuminator (grey)
DAY_ID = "day"              # days since the world was loaded: a heating hot spot warms by its rate each day
MAX_DAY = 3650
FOREIGN_STANDOFF_M = 0.08  # a foreign object hangs this far in front of the side it is dropped on
FOREIGN_MAX_SIZE_M = 2.0


class WorldError(ValueError):
    """A malformed world description or a value a face cannot take; the message says which."""


class Equipment(object):
    def __init__(self, spec):
        try:
            self.id = str(spec["id"])
            x, y, z = (float(v) for v in spec["position"])
            self.yaw = float(spec.get("yaw", 0.0))
            self.length, self.width = (float(v) for v in spec["footprint"])
            self.height = float(spec["height"])
        except (KeyError, TypeError, ValueError) as err:
            raise WorldError("equipment %r: %s" % (spec.get("id") if isinstance(spec, dict) else spec, err))
        self.position = np.array([x, y, z])
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        self.axis_x = np.array([c, s, 0.0])
        self.axis_y = np.array([-s, c, 0.0])

    def side_frame(self, side):
        """(centre of the side at ground level, outward normal, right unit vector, side width m)."""
        half_l, half_w = self.length / 2.0, self.width / 2.0
        if side == "front":
            normal, offset, width = self.axis_x, half_l, self.width
        elif side == "back":
            normal, offset, width = -self.axis_x, half_l, self.width
        elif side == "left":
            normal, offset, width = self.axis_y, half_w, self.length
        elif side == "right":
            normal, offset, width = -self.axis_y, half_w, self.length
        else:
            raise WorldError("equipment %s: unknown side %r (one of %s)" % (self.id, side, "|".join(SIDES)))
        up = np.array([0.0, 0.0, 1.0])
        right = np.cross(up, normal)
        return self.position + normal * offset, normal, right, width

    def side_quad(self, side):
        """The side as a Quad (the whole face of the box)."""
        base, normal, right, width = self.side_frame(side)
        centre = base + np.array([0.0, 0.0, self.height / 2.0])
        return Quad(centre, right, np.array([0.0, 0.0, 1.0]), width, self.height, normal)

    def top_quad(self):
        centre = self.position + np.array([0.0, 0.0, self.height])
        # seen from above: right = -axis_y when looking down with axis_x "up" in the picture
        return Quad(centre, -self.axis_y, self.axis_x, self.width, self.length, np.array([0.0, 0.0, 1.0]))


class Quad(object):
    """A planar rectangle: centre, unit right/up vectors in its plane, size in metres, normal."""

    def __init__(self, centre, right, up, width, height, normal):
        self.centre = np.asarray(centre, dtype=float)
        self.right = np.asarray(right, dtype=float)
        self.up = np.asarray(up, dtype=float)
        self.width = float(width)
        self.height = float(height)
        self.normal = np.asarray(normal, dtype=float)

    def point(self, fx, fy):
        """3D point at fractions (fx right, fy down) of the quad; (0, 0) = top-left corner."""
        return self.centre + (fx - 0.5) * self.width * self.right + (0.5 - fy) * self.height * self.up

    def corners(self):
        """Top-left, top-right, bottom-right, bottom-left (as seen from the front), shape (4, 3)."""
        return np.array([self.point(0, 0), self.point(1, 0), self.point(1, 1), self.point(0, 1)])


def _side_quad(equipment, side, center, size, standoff):
    base, normal, right, side_width = equipment.side_frame(side)
    u, v = (float(c) for c in center)
    w, h = (float(s) for s in size)
    if w <= 0 or h <= 0:
        raise WorldError("size must be positive")
    centre = base + normal * standoff + right * u + np.array([0.0, 0.0, v])
    return Quad(centre, right, np.array([0.0, 0.0, 1.0]), w, h, normal)


class Face(object):
    """A gauge, lamp, switch indicator or seven-segment display on an equipment side, with its
    current value. A display: ``digits`` cells, ``decimals`` places, ``polarity`` lit|dark,
    ``range`` [low, high] of its values; its window (DISPLAY_WINDOW of the face) shows display_text()."""

    def __init__(self, spec, equipment_by_id):
        self.id = str(spec.get("id", ""))
        if not self.id:
            raise WorldError("face without id: %r" % (spec,))
        try:
            self.equipment = equipment_by_id[spec["equipment"]]
            self.type = str(spec["type"])
            self.quad = _side_quad(self.equipment, spec["side"], spec["center"], spec["size"], FACE_STANDOFF_M)
        except KeyError as err:
            raise WorldError("face %s: missing or unknown %s" % (self.id, err))
        except (TypeError, ValueError) as err:
            raise WorldError("face %s: %s" % (self.id, err))
        if self.type not in FACE_TYPES:
            raise WorldError("face %s: type must be one of %s" % (self.id, "|".join(FACE_TYPES)))
        self.side = spec["side"]
        self.spec = dict(spec)
        if self.type == "gauge":
            self._init_gauge(spec)
        elif self.type == "display":
            self._init_display(spec)
        elif self.type == "lamp":
            self.color = str(spec.get("color", "red"))
            if self.color not in LAMP_COLORS:
                raise WorldError("face %s: lamp color must be one of %s" % (self.id, "|".join(LAMP_COLORS)))
        self.value = None
        self.set_value(spec.get("value"))

    def _init_gauge(self, spec):
        try:
            self.style = str(spec.get("style", "round_white"))
            self.range = tuple(float(v) for v in spec["range"])
            self.start_angle = float(spec.get("start_angle", -135.0))
            self.end_angle = float(spec.get("end_angle", 135.0))
            self.major_ticks = int(spec.get("major_ticks", 9))
            self.minor_ticks = int(spec.get("minor_ticks", 4))
            self.unit = str(spec.get("unit", ""))
            self.zones = [(float(a), float(b), str(c)) for a, b, c in spec.get("zones", [])]
            # a red drag (max) pointer left at this value beside the live needle; None: none
            self.drag = float(spec["drag"]) if spec.get("drag") is not None else None
            # the needle's counterweight tail beyond the pivot, in dial radii (a disc at its end over 0.25)
            self.tail = float(spec.get("tail", 0.15))
        except (KeyError, TypeError, ValueError) as err:
            raise WorldError("gauge %s: %s" % (self.id, err))
        if self.drag is not None and not self.range[0] <= self.drag <= self.range[1] or not 0.0 <= self.tail <= 0.7:
            raise WorldError("gauge %s: drag must lie in the range, tail in 0..0.7 dial radii" % self.id)
        if self.style not in GAUGE_STYLES:
            raise WorldError("gauge %s: style must be one of %s" % (self.id, "|".join(GAUGE_STYLES)))
        if len(self.range) != 2 or not self.range[0] < self.range[1]:
            raise WorldError("gauge %s: range must be [low, high] with low < high" % self.id)
        if self.major_ticks < 2 or self.minor_ticks < 0 or self.start_angle == self.end_angle:
            raise WorldError("gauge %s: needs >= 2 major ticks and start_angle != end_angle" % self.id)
        if any(c not in ZONE_COLORS for _, _, c in self.zones):
            raise WorldError("gauge %s: zone colours must be one of %s" % (self.id, "|".join(ZONE_COLORS)))

    def _init_display(self, spec):
        try:
            self.digits = int(spec.get("digits", 4))
            self.decimals = int(spec.get("decimals", 1))
            self.polarity = str(spec.get("polarity", "lit"))
            self.style = str(spec.get("style", "segments"))   # or drum: printed digits on wheels, leading zeros shown
            self.range = tuple(float(v) for v in spec["range"])
        except (KeyError, TypeError, ValueError) as err:
            raise WorldError("display %s: %s" % (self.id, err))
        if not 1 <= self.digits <= 12 or not 0 <= self.decimals < self.digits or self.polarity not in ("lit", "dark"):
            raise WorldError("display %s: needs 1..12 digits, fewer decimals, polarity lit|dark" % self.id)
        if len(self.range) != 2 or not self.range[0] < self.range[1]:
            raise WorldError("display %s: range must be [low, high] with low < high" % self.id)
        if self.style not in ("segments", "drum") or (self.style == "drum" and self.range[0] < 0):
            raise WorldError("display %s: style must be segments or drum (a drum counts from 0)" % self.id)

    def display_text(self, value=None):
        """What a display shows for ``value`` (default: current): right-aligned, blank leading digits
        (a drum's wheels show zeros)."""
        value = self.value if value is None else value
        text = "%.*f" % (self.decimals, value)
        if self.style == "drum":
            return "0" * (self.digits - len(text.replace(".", ""))) + text
        return " " * (self.digits - len(text.replace(".", ""))) + text

    def parse_value(self, value):
        """The canonical value for ``value`` (a string from a service or a YAML scalar)."""
        if self.type == "display":
            try:
                number = round(float(value), self.decimals)
            except (TypeError, ValueError):
                raise WorldError("display %s: value must be a number, got '%s'" % (self.id, value))
            if not math.isfinite(number) or not self.range[0] <= number <= self.range[1] \
                    or len(("%.*f" % (self.decimals, number)).replace(".", "")) > self.digits:
                raise WorldError("display %s: value out of range [%g, %g] or wider than %d digits: %s"
                                 % (self.id, self.range[0], self.range[1], self.digits, value))
            return number
        if self.type == "gauge":
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise WorldError("gauge %s: value must be a number, got '%s'" % (self.id, value))
            if not math.isfinite(number) or not self.range[0] <= number <= self.range[1]:
                raise WorldError("gauge %s: value out of range [%g, %g]: %s"
                                 % (self.id, self.range[0], self.range[1], value))
            return number
        if value is True or value is False:   # YAML 1.1 reads on/off as booleans
            value = "on" if value else "off"
        allowed = LAMP_VALUES if self.type == "lamp" else SWITCH_VALUES
        if str(value) not in allowed:
            raise WorldError("%s %s: value must be one of %s, got '%s'"
                             % (self.type, self.id, "|".join(allowed), value))
        return str(value)

    def set_value(self, value):
        self.value = self.parse_value(value)
        return self.value

    # --- gauge geometry (shared by the texture painter and the ground truth) -----------------
    def needle_angle_deg(self, value=None):
        """Needle angle, degrees clockwise from 12 o'clock, for ``value`` (default: current)."""
        value = self.value if value is None else value
        low, high = self.range
        frac = (min(max(value, low), high) - low) / (high - low)
        return self.start_angle + frac * (self.end_angle - self.start_angle)

    def dial_layout(self):
        """(pivot fx, pivot fy, dial radius m): pivot as fractions of the face (x right, y down)."""
        w, h = self.quad.width, self.quad.height
        if self.style == "panel_arc":
            reach = max(abs(math.sin(math.radians(a))) for a in (self.start_angle, self.end_angle))
            radius = min(0.78 * h, 0.45 * w / max(reach, 1e-3))
            return 0.5, 0.9, radius
        return 0.5, 0.5, 0.46 * min(w, h)

    def needle_length_m(self):
        return 0.85 * self.dial_layout()[2]

    def needle_tip_fraction(self, value=None):
        """Needle tip as fractions of the face (x right, y down)."""
        px, py, _ = self.dial_layout()
        theta = math.radians(self.needle_angle_deg(value))
        length = self.needle_length_m()
        return (px + length * math.sin(theta) / self.quad.width,
                py - length * math.cos(theta) / self.quad.height)


class HotSpot(object):
    """A hot joint or bushing: a flat core of ``radius`` m at ``temperature`` degC on a side.

    ``phase``, ``device``, ``equipment_class`` (optional) go to its calibration as they are
    (thermal diagnosis, checked by the calibration schema); ``phase: ambient`` makes it an ambient
    reference plate, calibrated with a box inside its core. ``heating`` (K per day, optional): a
    joint going bad, ``temperature`` on day 0 and that much warmer every day after (World's day)."""

    CALIBRATION_KEYS = ("phase", "device", "equipment_class")

    def __init__(self, spec, equipment_by_id):
        self.id = str(spec.get("id", ""))
        try:
            self.equipment = equipment_by_id[spec["equipment"]]
            self.radius = float(spec["radius"])
            if self.radius <= 0:
                raise ValueError("radius must be positive")
            # the texture spans the core and a fade ring of one radius: 4 radii square
            self.quad = _side_quad(self.equipment, spec["side"], spec["center"],
                                   [4 * self.radius, 4 * self.radius], 2 * FACE_STANDOFF_M)
        except KeyError as err:
            raise WorldError("hot spot %s: missing or unknown %s" % (self.id, err))
        except (TypeError, ValueError) as err:
            raise WorldError("hot spot %s: %s" % (self.id, err))
        self.type = "hot_spot"
        self.calibration = dict((k, spec[k]) for k in self.CALIBRATION_KEYS if k in spec)
        self.value = None
        self.set_value(spec.get("temperature"))
        self.day0_c, self.heating = self.value, spec.get("heating", 0.0)
        if isinstance(self.heating, bool) or not isinstance(self.heating, (int, float)) \
                or not math.isfinite(self.heating):
            raise WorldError("hot spot %s: heating must be K per day, got '%s'" % (self.id, self.heating))

    def on_day(self, day):
        """A heating spot's temperature on ``day`` (within HOT_SPOT_RANGE_C): its value from now on."""
        if self.heating:
            low, high = HOT_SPOT_RANGE_C
            self.value = min(high, max(low, self.day0_c + self.heating * day))
        return self.value

    def parse_value(self, value):
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise WorldError("hot spot %s: temperature must be a number, got '%s'" % (self.id, value))
        if not math.isfinite(number) or not HOT_SPOT_RANGE_C[0] <= number <= HOT_SPOT_RANGE_C[1]:
            raise WorldError("hot spot %s: temperature out of range [%g, %g]: %s"
                             % ((self.id,) + HOT_SPOT_RANGE_C + (value,)))
        return number

    def set_value(self, value):
        self.value = self.parse_value(value)
        return self.value

    @property
    def temperature(self):
        return self.value


class ForeignObject(object):
    """Something that does not belong on the equipment (a bird's nest, hanging debris): a textured
    plate ``FOREIGN_STANDOFF_M`` in front of a side. Its value is the placement text
    ``equipment,side,u,v,w,h`` (m, like a face's center and size) or ``""`` when absent."""

    def __init__(self, item_id, equipment_by_id):
        self.id = item_id
        self.type = "foreign"
        self.equipment = None
        self.quad = None
        self.value = ""
        self._equipment_by_id = equipment_by_id

    def parse_value(self, value):
        text = "" if value is None else str(value).strip()
        if not text:
            return None, None, ""
        fields = text.split(",")
        if len(fields) != 6:
            raise WorldError("foreign object %s: value must be 'equipment,side,u,v,w,h' or empty, got '%s'"
                             % (self.id, text))
        equipment = self._equipment_by_id.get(fields[0])
        if equipment is None:
            raise WorldError("foreign object %s: unknown equipment '%s'" % (self.id, fields[0]))
        if fields[1] not in SIDES:
            raise WorldError("foreign object %s: side must be one of %s" % (self.id, "|".join(SIDES)))
        try:
            u, v, w, h = (float(f) for f in fields[2:])
        except ValueError:
            raise WorldError("foreign object %s: u,v,w,h must be numbers, got '%s'" % (self.id, text))
        if not all(math.isfinite(n) for n in (u, v, w, h)) or not (0 < w <= FOREIGN_MAX_SIZE_M
                                                                   and 0 < h <= FOREIGN_MAX_SIZE_M):
            raise WorldError("foreign object %s: size must be within (0, %g] m" % (self.id, FOREIGN_MAX_SIZE_M))
        quad = _side_quad(equipment, fields[1], (u, v), (w, h), FOREIGN_STANDOFF_M)
        return equipment, quad, "%s,%s,%g,%g,%g,%g" % (equipment.id, fields[1], u, v, w, h)

    def set_value(self, value):
        self.equipment, self.quad, self.value = self.parse_value(value)
        return self.value

    @property
    def present(self):
        return self.quad is not None


class Light(object):
    """The yard's light, ``day`` or ``night`` (sim/set_world_value light night): at night the visible
    camera switches to its infrared mode, a grey picture lit by its own illuminator (sim.render)."""

    id = LIGHT_ID
    type = "light"

    def __init__(self, value="day"):
        self.value = None
        self.set_value(value)

    def set_value(self, value):
        if value not in ("day", "night"):
            raise WorldError("light must be day or night, got '%s'" % (value,))
        self.value = value
        return value


class Day(object):
    """Days since the world was loaded (sim/set_world_value day 12): every heating hot spot is set
    to its temperature on that day (a value set on a spot by hand lasts until the day changes)."""

    id = DAY_ID
    type = "day"

    def __init__(self, spots):
        self.spots = spots
        self.value = 0

    def set_value(self, value):
        try:
            day = int(str(value))
        except ValueError:
            raise WorldError("day must be a whole number of days, got '%s'" % (value,))
        if not 0 <= day <= MAX_DAY:
            raise WorldError("day out of range [0, %d]: %s" % (MAX_DAY, value))
        for spot in self.spots.values():
            spot.on_day(day)
        self.value = day
        return day


class World(object):
    """The yard: equipment, faces, hot spots, thermal surface temperatures, robot start."""

    def __init__(self, spec):
        if not isinstance(spec, dict):
            raise WorldError("world description must be a mapping")
        try:
            self.size = tuple(float(v) for v in spec.get("size", (60.0, 40.0)))
            self.fence_margin = float(spec.get("fence_margin", 1.0))
            robot = spec.get("robot", {})
            self.start_pose = tuple(float(v) for v in robot.get("start_pose", (0.0, 0.0, 0.0)))
            self.sensor_height = float(robot.get("sensor_height", 1.2))
            self.seed = int(spec.get("seed", 0))
        except (TypeError, ValueError) as err:
            raise WorldError("world: %s" % err)
        self.equipment = {}
        for item in spec.get("equipment", []):
            eq = Equipment(item)
            self.equipment[eq.id] = eq
        self.faces = {}
        for item in spec.get("faces", []) or []:
            face = Face(item, self.equipment)
            self._add_unique(self.faces, face)
        thermal = spec.get("thermal", {}) or {}
        try:
            self.ambient_c = float(thermal.get("ambient", 25.0))
            self.ground_c = float(thermal.get("ground", self.ambient_c))
            self.sky_c = float(thermal.get("sky", -10.0))
            self.equipment_c = {str(k): float(v) for k, v in (thermal.get("equipment", {}) or {}).items()}
        except (TypeError, ValueError, AttributeError) as err:
            raise WorldError("world thermal: %s" % err)
        self.foreign = {}
        self.light = Light(spec.get(LIGHT_ID, "day"))
        self.hot_spots = {}
        for item in thermal.get("hot_spots", []) or []:
            spot = HotSpot(item, self.equipment)
            if spot.id in self.faces:
                raise WorldError("duplicate id %s" % spot.id)
            self._add_unique(self.hot_spots, spot)
        self.day = Day(self.hot_spots)

    @staticmethod
    def _add_unique(table, item):
        if item.id in table:
            raise WorldError("duplicate id %s" % item.id)
        table[item.id] = item

    @classmethod
    def load(cls, path):
        """Load the ``world:`` mapping of a YAML file (config/sim_world.yaml)."""
        with open(path) as stream:
            doc = yaml.safe_load(stream)
        if not isinstance(doc, dict) or "world" not in doc:
            raise WorldError("%s: no 'world' mapping" % path)
        return cls(doc["world"])

    def surface_temperature(self, equipment_id):
        return self.equipment_c.get(equipment_id, self.ambient_c)

    def item(self, item_id):
        """A face, hot spot, foreign object, the light or the day; a foreign object id (``foreign/<name>``) is created
        on first use."""
        if item_id == LIGHT_ID:
            return self.light
        if item_id == DAY_ID:
            return self.day
        item = self.faces.get(item_id) or self.hot_spots.get(item_id) or self.foreign.get(item_id)
        if item is None and str(item_id).startswith(FOREIGN_PREFIX) and len(str(item_id)) > len(FOREIGN_PREFIX):
            item = self.foreign[item_id] = ForeignObject(str(item_id), self.equipment)
        if item is None:
            raise WorldError("unknown face or hot spot '%s'" % (item_id,))
        return item

    def set_value(self, item_id, value):
        """Set a face's value, a hot spot's temperature or a foreign object's placement; returns the canonical value."""
        return self.item(item_id).set_value(value)

    def get_value(self, item_id):
        return self.item(item_id).value

    def values(self):
        """Every settable value: {id: value}."""
        result = {fid: f.value for fid, f in self.faces.items()}
        result.update({sid: s.value for sid, s in self.hot_spots.items()})
        result.update({oid: o.value for oid, o in self.foreign.items()})
        result[LIGHT_ID] = self.light.value
        result[DAY_ID] = self.day.value
        return result

    def apply_values(self, values):
        """Set many values at once (e.g. from the simulator's world_state); unknown ids are errors. The
        day first: a heating spot's value given beside it is its value on that day."""
        for item_id, value in sorted(values.items(), key=lambda item: item[0] != DAY_ID):
            self.set_value(item_id, value)
