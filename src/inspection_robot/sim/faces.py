"""Paints the textures of equipment faces (gauges, lamps, switch indicators) and yard surfaces.

Face textures depend only on the face and its value, so the renderer caches them and warps them
into each frame. Gauges are drawn crisp (anti-aliased ticks, a dark tapered needle, a pivot cap)
so that meter reading on rendered pictures is a fair test. The geometry (pivot, dial radius,
needle angle) comes from ``sim.world.Face`` so the ground truth and the picture agree.
"""
import math

import numpy as np

from inspection_robot.inspection.digital import render_display
from inspection_robot.inspection.drum import render_drum
from inspection_robot.lazy import lazy_import
from inspection_robot.sim.world import DISPLAY_WINDOW

cv2 = lazy_import("cv2")   # on first use: a node registers before its ~360 libraries load

SUBPIXEL_SHIFT = 4
_SCALE = 1 << SUBPIXEL_SHIFT
BGR = {"red": (40, 40, 210), "green": (60, 170, 40), "yellow": (30, 200, 230), "white": (235, 235, 235),
       "blue": (200, 110, 30), "black": (20, 20, 20)}
LAMP_OFF = {"red": (40, 40, 90), "green": (40, 80, 40), "yellow": (40, 90, 100), "white": (110, 110, 110),
            "blue": (90, 60, 40)}


def _pt(x, y):
    return (int(round(x * _SCALE)), int(round(y * _SCALE)))


def _line(img, p0, p1, color, thickness):
    cv2.line(img, _pt(*p0), _pt(*p1), color, max(1, int(round(thickness))), cv2.LINE_AA, SUBPIXEL_SHIFT)


def _circle(img, centre, radius, color, thickness=-1):
    cv2.circle(img, _pt(*centre), int(round(radius * _SCALE)), color,
               thickness if thickness < 0 else max(1, int(round(thickness))), cv2.LINE_AA, SUBPIXEL_SHIFT)


def texture_size(face, longest_px):
    """(width, height) in pixels for a face texture whose longer side is ``longest_px``."""
    w, h = face.quad.width, face.quad.height
    scale = longest_px / max(w, h)
    return max(8, int(round(w * scale))), max(8, int(round(h * scale)))


def paint_face(face, longest_px):
    """BGR texture of ``face`` at its current value, the longer side ``longest_px`` pixels."""
    width, height = texture_size(face, longest_px)
    img = np.empty((height, width, 3), np.uint8)
    img[:] = (150, 150, 145)  # mounting plate
    border = max(1, int(round(0.03 * min(width, height))))
    cv2.rectangle(img, (0, 0), (width - 1, height - 1), (70, 70, 70), border)
    if face.type == "gauge":
        paint_gauge(img, face)
    elif face.type == "lamp":
        _paint_lamp(img, face)
    elif face.type == "display":
        _paint_display(img, face)
    else:
        _paint_switch(img, face)
    return img


def _paint_display(img, face):
    """A seven-segment display (inspection.digital.render_display) or a drum counter's wheels
    (inspection.drum.render_drum) in the face's window."""
    height, width = img.shape[:2]
    left, top, right, bottom = DISPLAY_WINDOW
    x0, y0, x1, y1 = (int(round(left * width)), int(round(top * height)), int(round(right * width)),
                      int(round(bottom * height)))
    if face.style == "drum":
        wheels = [float(c) for c in face.display_text().replace(".", "")]
        img[y0:y1, x0:x1] = render_drum(wheels, x1 - x0, y1 - y0, polarity=face.polarity)
    else:
        img[y0:y1, x0:x1] = render_display(face.display_text(), x1 - x0, y1 - y0, polarity=face.polarity,
                                           slant_deg=6.0)


def paint_gauge(img, face):
    """Paint a pointer gauge into ``img`` (the whole face). ``face`` gives the geometry like
    ``sim.world.Face``: quad.width (m), dial_layout(), style, range, zones, needle_angle_deg(),
    start_angle, end_angle, major_ticks, minor_ticks, unit, needle_length_m(); an optional
    ``colours`` (dial, ink, needle BGR) overrides the style's colours (test fixtures)."""
    height, width = img.shape[:2]
    px_per_m = width / face.quad.width
    fx, fy, radius_m = face.dial_layout()
    cx, cy, radius = fx * width, fy * height, radius_m * px_per_m
    dark_dial = face.style == "round_black"
    ink = (245, 245, 245) if dark_dial else (15, 15, 15)
    colours = getattr(face, "colours", None)
    dial_colour = (25, 25, 25) if dark_dial else (240, 240, 236)
    if colours is not None:
        dial_colour, ink = colours[0], colours[1]
    if face.style == "panel_arc":
        cv2.rectangle(img, (int(0.06 * width), int(0.06 * height)),
                      (int(0.94 * width), int(0.94 * height)), (240, 240, 236), -1)
    else:
        _circle(img, (cx, cy), radius * 1.08, (60, 60, 60))           # bezel
        _circle(img, (cx, cy), radius, dial_colour)
    low, high = face.range
    tick_outer = radius * 0.95
    # coloured zones: a band just inside the tick tips
    for z_low, z_high, colour in face.zones:
        a0, a1 = face.needle_angle_deg(z_low), face.needle_angle_deg(z_high)
        band = max(2.0, radius * 0.08)
        cv2.ellipse(img, _pt(cx, cy), _pt(tick_outer - band / 2, tick_outer - band / 2),
                    0, min(a0, a1) - 90, max(a0, a1) - 90, BGR[colour], int(round(band)), cv2.LINE_AA,
                    SUBPIXEL_SHIFT)
    # scale arc and ticks
    a_start, a_end = face.start_angle, face.end_angle
    cv2.ellipse(img, _pt(cx, cy), _pt(tick_outer, tick_outer), 0, min(a_start, a_end) - 90,
                max(a_start, a_end) - 90, ink, max(1, int(round(radius * 0.012))), cv2.LINE_AA, SUBPIXEL_SHIFT)
    majors = face.major_ticks
    minors = face.minor_ticks
    steps = (majors - 1) * (minors + 1)
    font = cv2.FONT_HERSHEY_SIMPLEX
    font_scale = radius / 260.0
    for i in range(steps + 1):
        value = low + (high - low) * i / float(steps)
        theta = math.radians(face.needle_angle_deg(value))
        major = i % (minors + 1) == 0
        length = radius * (0.16 if major else 0.08)
        thick = radius * (0.025 if major else 0.012)
        sx, sy = math.sin(theta), -math.cos(theta)
        _line(img, (cx + sx * tick_outer, cy + sy * tick_outer),
              (cx + sx * (tick_outer - length), cy + sy * (tick_outer - length)), ink, thick)
        if major and font_scale > 0.12:
            label = "%g" % round(value, 6)
            (tw, th), _ = cv2.getTextSize(label, font, font_scale, 1)
            r_text = tick_outer - radius * 0.30
            org = (cx + sx * r_text - tw / 2.0, cy + sy * r_text + th / 2.0)
            cv2.putText(img, label, (int(org[0]), int(org[1])), font, font_scale, ink,
                        max(1, int(round(font_scale * 2))), cv2.LINE_AA)
    if face.unit and font_scale > 0.12:
        (tw, th), _ = cv2.getTextSize(face.unit, font, font_scale * 1.2, 1)
        uy = cy + radius * (0.45 if face.style != "panel_arc" else -0.35)
        cv2.putText(img, face.unit, (int(cx - tw / 2.0), int(uy + th / 2.0)), font, font_scale * 1.2, ink,
                    max(1, int(round(font_scale * 2))), cv2.LINE_AA)
    drag = getattr(face, "drag", None)
    if drag is not None:        # a thin red drag pointer, under the live needle
        theta = math.radians(face.needle_angle_deg(drag))
        _line(img, (cx, cy), (cx + math.sin(theta) * radius * 0.9, cy - math.cos(theta) * radius * 0.9),
              (30, 30, 210), max(1.0, radius * 0.018))
    # needle: a tapered polygon from its tail through the pivot to the tip
    theta = math.radians(face.needle_angle_deg())
    sx, sy = math.sin(theta), -math.cos(theta)
    nx, ny = -sy, sx
    length = face.needle_length_m() * px_per_m
    tail = radius * getattr(face, "tail", 0.15)
    half_base = max(1.5, radius * 0.035)
    needle_colour = (30, 30, 200) if dark_dial else (20, 20, 20)
    if dark_dial:
        needle_colour = (40, 60, 230)
    if colours is not None:
        needle_colour = colours[2]
    poly = np.array([_pt(cx + sx * length, cy + sy * length),
                     _pt(cx - sx * tail + nx * half_base, cy - sy * tail + ny * half_base),
                     _pt(cx - sx * tail - nx * half_base, cy - sy * tail - ny * half_base)], np.int32)
    cv2.fillConvexPoly(img, poly, needle_colour, cv2.LINE_AA, SUBPIXEL_SHIFT)
    if tail > radius * 0.25:    # a counterweight: a disc near the tail's end
        _circle(img, (cx - sx * tail * 0.85, cy - sy * tail * 0.85), radius * 0.08, needle_colour)
    _circle(img, (cx, cy), max(2.0, radius * 0.07), (50, 50, 50))


def _paint_lamp(img, face):
    height, width = img.shape[:2]
    cx, cy, radius = width / 2.0, height / 2.0, 0.4 * min(width, height)
    _circle(img, (cx, cy), radius * 1.12, (40, 40, 40))
    if face.value == "on":
        _circle(img, (cx, cy), radius, BGR[face.color])
        _circle(img, (cx - radius * 0.3, cy - radius * 0.3), radius * 0.25, (250, 250, 250))
    else:
        _circle(img, (cx, cy), radius, LAMP_OFF[face.color])


def _paint_switch(img, face):
    height, width = img.shape[:2]
    cx, cy, radius = width / 2.0, height * 0.45, 0.36 * min(width, height)
    closed = face.value == "closed"
    _circle(img, (cx, cy), radius * 1.1, (40, 40, 40))
    _circle(img, (cx, cy), radius, BGR["red"] if closed else BGR["green"])
    half = radius * 0.75
    bar = max(2.0, radius * 0.22)
    if closed:   # bar in line with the circuit
        _line(img, (cx, cy - half), (cx, cy + half), (250, 250, 250), bar)
    else:
        _line(img, (cx - half, cy), (cx + half, cy), (250, 250, 250), bar)
    font_scale = min(width, height) / 160.0
    if font_scale > 0.15:
        label = "ON" if closed else "OFF"
        (tw, th), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, font_scale, 1)
        cv2.putText(img, label, (int(cx - tw / 2.0), int(height * 0.93)), cv2.FONT_HERSHEY_SIMPLEX,
                    font_scale, (20, 20, 20), max(1, int(round(font_scale * 2))), cv2.LINE_AA)


# --- yard surfaces (procedural, seeded) -----------------------------------------------------
def _value_noise(rng, height, width, cell):
    """Smooth random field in [0, 1): random values on a coarse grid, bicubically upsampled."""
    grid = rng.rand(height // cell + 2, width // cell + 2).astype(np.float32)
    return cv2.resize(grid, (width, height), interpolation=cv2.INTER_CUBIC)[:height, :width]


def paint_ground(rng, width, height, px_per_m, yard_origin_px, yard_size_m):
    """Gravel with concrete paths and painted lines: multi-scale structure for feature matching."""
    field = (0.45 * _value_noise(rng, height, width, 64) + 0.35 * _value_noise(rng, height, width, 8)
             + 0.2 * rng.rand(height, width).astype(np.float32))
    img = np.empty((height, width, 3), np.uint8)
    base = 95 + 70 * field
    img[..., 0] = np.clip(base * 0.92, 0, 255)
    img[..., 1] = np.clip(base * 0.97, 0, 255)
    img[..., 2] = np.clip(base, 0, 255)
    ox, oy = yard_origin_px
    yw, yh = yard_size_m
    # concrete roads: a grid every 12 m, 3 m wide, with a dashed centre line
    for x_m in np.arange(4.0, yw, 12.0):
        x0 = int(ox + (x_m - 1.5) * px_per_m)
        cv2.rectangle(img, (x0, int(oy)), (x0 + int(3 * px_per_m), int(oy + yh * px_per_m)), (168, 170, 172), -1)
    for y_m in np.arange(5.0, yh, 12.0):
        y0 = int(oy + (y_m - 1.5) * px_per_m)
        cv2.rectangle(img, (int(ox), y0), (int(ox + yw * px_per_m), y0 + int(3 * px_per_m)), (168, 170, 172), -1)
    for y_m in np.arange(5.0, yh, 12.0):
        for x_m in np.arange(0.0, yw, 2.0):
            p0 = (int(ox + x_m * px_per_m), int(oy + y_m * px_per_m))
            cv2.line(img, p0, (p0[0] + int(px_per_m), p0[1]), (40, 200, 230), max(1, int(0.12 * px_per_m)))
    speckle = (rng.rand(height, width) * 30 - 15).astype(np.int16)
    return np.clip(img.astype(np.int16) + speckle[..., None], 0, 255).astype(np.uint8)


def paint_panel(rng, width, height, colour, label=None):
    """Painted metal skin of a box or wall: panel seams, bolts, stains and an optional label."""
    field = 0.6 * _value_noise(rng, height, width, 32) + 0.4 * rng.rand(height, width).astype(np.float32)
    img = np.empty((height, width, 3), np.uint8)
    for ch in range(3):
        img[..., ch] = np.clip(colour[ch] * (0.85 + 0.3 * field), 0, 255)
    step = max(8, width // max(1, width // 60))
    for x in range(step, width, step):
        cv2.line(img, (x, 0), (x, height - 1), [int(c * 0.55) for c in colour], 2)
        for y in range(10, height, 40):
            cv2.circle(img, (x - 6, y), 3, (50, 50, 50), -1)
    for _ in range(max(1, width * height // 20000)):
        x, y = int(rng.randint(0, width)), int(rng.randint(0, height))
        size = int(rng.randint(4, 20))
        cv2.rectangle(img, (x, y), (x + size, y + size // 2), [int(c * 0.7) for c in colour], -1)
    if label:
        scale = max(0.5, width / 400.0)
        cv2.rectangle(img, (10, 10), (int(10 + 22 * scale * len(label)), int(10 + 40 * scale)), (235, 235, 235), -1)
        cv2.putText(img, label, (16, int(10 + 30 * scale)), cv2.FONT_HERSHEY_SIMPLEX, scale, (20, 20, 20),
                    max(1, int(2 * scale)), cv2.LINE_AA)
    return img


def paint_foreign(seed, width, height):
    """A bird's nest / hanging debris: dark twigs criss-crossing over a brown tangle."""
    rng = np.random.RandomState(seed % (2 ** 31))
    field = _value_noise(rng, height, width, max(4, min(width, height) // 6))
    img = np.empty((height, width, 3), np.uint8)
    for ch, base in enumerate((40, 70, 105)):
        img[..., ch] = np.clip(base * (0.6 + 0.8 * field), 0, 255)
    for _ in range(max(20, width * height // 150)):
        x0, y0 = rng.randint(0, width), rng.randint(0, height)
        angle, length = rng.uniform(0, math.pi), rng.uniform(0.2, 0.6) * max(width, height)
        x1, y1 = int(x0 + length * math.cos(angle)), int(y0 + length * math.sin(angle))
        shade = int(rng.randint(15, 90))
        cv2.line(img, (int(x0), int(y0)), (x1, y1), (shade // 2, shade, int(shade * 1.5)),
                 max(1, int(min(width, height) / 40)))
    return img


def paint_hot_spot(size_px):
    """Float32 profile of a hot spot spanning 4 radii: 1 on the core (r <= R), fading to 0 at 2R."""
    coords = (np.arange(size_px, dtype=np.float32) + 0.5) / size_px * 4.0 - 2.0   # in radii
    xx, yy = np.meshgrid(coords, coords)
    r = np.sqrt(xx * xx + yy * yy)
    profile = np.where(r <= 1.0, 1.0, 0.5 + 0.5 * np.cos(np.clip(r - 1.0, 0.0, 1.0) * np.pi))
    return profile.astype(np.float32)
