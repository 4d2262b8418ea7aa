"""A simulated Pelco-D pan/tilt head, speaking the bytes over a pseudo-terminal.

:class:`SimPelcoHead` is the device model: finite slew speed (continuous moves at the speed byte's
rate, absolute moves at the preset speed, shortest way round for pan), tilt limits, query replies
(0x59/0x5B with the PHYSICAL angle), wiper and lamp state, and injectable faults:

- ``silence``: the head ignores everything (a dead or unplugged RS485 line);
- ``bad_checksum``: replies carry a wrong checksum;
- ``garbage``: random bytes (with stray 0xFF) precede every reply.

:class:`PtyPelcoServer` creates a pseudo-terminal, points a fixed symlink at its slave side (the
path the driver opens) and answers frames arriving on the master side. ``unplug`` closes the pty
and removes the link, ``replug`` makes a new one: the driver sees a vanished port and reconnects.
The motion state is advanced from a monotonic clock whenever it is read, so no tick is needed.
"""
import os
import random
import select
import threading
import time
import tty

from inspection_robot.ptz import pelco

FAULTS = ("none", "silence", "bad_checksum", "garbage")


class SimPelcoHead(object):
    """Device model; angles are kept in STANDARD hundredths of a degree (floats while moving)."""

    def __init__(self, address=pelco.DEFAULT_ADDRESS, max_speed_deg_s=60.0, position_speed_deg_s=90.0,
                 tilt_limits_centi=(-9000, 9000), clock=time.monotonic, seed=0):
        self.address = int(address)
        self.max_speed = float(max_speed_deg_s) * 100.0          # centi-degrees per second
        self.position_speed = float(position_speed_deg_s) * 100.0
        self.tilt_limits = (float(tilt_limits_centi[0]), float(tilt_limits_centi[1]))
        self._clock = clock
        self._last = clock()
        self._lock = threading.Lock()
        self._random = random.Random(seed)
        self.pan = 0.0
        self.tilt = 0.0
        self.pan_rate = 0.0        # centi-degrees/s, standard sign; continuous move
        self.tilt_rate = 0.0
        self.pan_target = None     # absolute move target, standard centi
        self.tilt_target = None
        self.wiper = False
        self.lamp = False
        self.fault = "none"
        self.frames_handled = 0

    # --- motion ----------------------------------------------------------------------------
    def _advance(self):
        now = self._clock()
        dt = max(0.0, now - self._last)
        self._last = now
        if self.pan_target is not None:
            error = pelco.wrap_pan_centi(int(round(self.pan_target - self.pan)))
            step = self.position_speed * dt
            if abs(error) <= step:
                self.pan, self.pan_target = float(self.pan_target), None
            else:
                self.pan += step if error > 0 else -step
        else:
            self.pan += self.pan_rate * dt
        self.pan = _wrap_float(self.pan)
        if self.tilt_target is not None:
            error = self.tilt_target - self.tilt
            step = self.position_speed * dt
            if abs(error) <= step:
                self.tilt, self.tilt_target = float(self.tilt_target), None
            else:
                self.tilt += step if error > 0 else -step
        else:
            self.tilt += self.tilt_rate * dt
        self.tilt = min(max(self.tilt, self.tilt_limits[0]), self.tilt_limits[1])

    def state(self):
        """(pan_centi, tilt_centi, wiper, lamp) now, standard, rounded to hundredths."""
        with self._lock:
            self._advance()
            return (pelco.wrap_pan_centi(int(round(self.pan))), int(round(self.tilt)), self.wiper, self.lamp)

    def moving(self):
        """True while a continuous or absolute move is under way (a stop frame ends both)."""
        with self._lock:
            return bool(self.pan_rate or self.tilt_rate or self.pan_target is not None
                        or self.tilt_target is not None)

    def _speed(self, byte):
        if byte >= pelco.TURBO_SPEED:
            return self.max_speed * 1.5
        return self.max_speed * byte / float(pelco.MAX_SPEED)

    # --- protocol ---------------------------------------------------------------------------
    def handle(self, frame):
        """Apply one decoded frame; return the reply bytes (b"" if none)."""
        if self.fault == "silence" or frame.address != self.address:
            return b""
        with self._lock:
            self._advance()
            self.frames_handled += 1
            reply = self._apply(frame)
        if not reply:
            return reply
        if self.fault == "bad_checksum":
            reply = reply[:6] + bytes([(reply[6] + 1) & 0xFF])
        elif self.fault == "garbage":
            junk = bytes(self._random.choice((0xFF, 0x00, 0x59, 0x12, 0xA5)) for _ in range(5))
            reply = junk + reply
        return reply

    def _apply(self, frame):
        cmd2 = frame.cmd2
        if frame.cmd1 == 0 and cmd2 == pelco.CMD_SET_PAN:
            try:
                self.pan_target = float(pelco.pan_physical_to_standard(frame.data))
            except ValueError:
                return b""          # a real head ignores an impossible angle
            self.pan_rate = 0.0
        elif frame.cmd1 == 0 and cmd2 == pelco.CMD_SET_TILT:
            try:
                target = pelco.tilt_physical_to_standard(frame.data)
            except ValueError:
                return b""
            self.tilt_target = min(max(float(target), self.tilt_limits[0]), self.tilt_limits[1])
            self.tilt_rate = 0.0
        elif frame.cmd1 == 0 and cmd2 == pelco.CMD_QUERY_PAN:
            physical = pelco.pan_standard_to_physical(pelco.wrap_pan_centi(int(round(self.pan))))
            return pelco.pan_reply(self.address, physical)
        elif frame.cmd1 == 0 and cmd2 == pelco.CMD_QUERY_TILT:
            return pelco.tilt_reply(self.address, pelco.tilt_standard_to_physical(int(round(self.tilt))))
        elif frame.cmd1 == 0 and cmd2 in (pelco.CMD_SET_AUX, pelco.CMD_CLEAR_AUX) and frame.data1 == 0:
            on = cmd2 == pelco.CMD_SET_AUX
            if frame.data2 == pelco.AUX_WIPER:
                self.wiper = on
            elif frame.data2 == pelco.AUX_LAMP:
                self.lamp = on
        elif frame.cmd1 == 0 and cmd2 & 0x01 == 0 and cmd2 <= 0x1E:
            self._direction(cmd2, frame.data1, frame.data2)
        return b""

    def _direction(self, bits, pan_speed, tilt_speed):
        """Standard command: direction bits and speeds (all zero = stop)."""
        self.pan_target = self.tilt_target = None
        pan = (1 if bits & pelco.DIR_LEFT else 0) - (1 if bits & pelco.DIR_RIGHT else 0)
        tilt = (1 if bits & pelco.DIR_DOWN else 0) - (1 if bits & pelco.DIR_UP else 0)
        self.pan_rate = pan * self._speed(pan_speed)
        self.tilt_rate = tilt * self._speed(min(tilt_speed, pelco.MAX_SPEED))


def _wrap_float(centi):
    wrapped = centi % pelco.FULL_TURN
    return wrapped - pelco.FULL_TURN if wrapped > pelco.HALF_TURN else wrapped


class PtyPelcoServer(object):
    """Serves ``head`` on a pseudo-terminal whose slave side is reachable at ``link_path``."""

    def __init__(self, head, link_path, logger=None):
        self.head = head
        self.link_path = link_path
        self._log = logger or (lambda text: None)
        self._master = self._slave = None
        self._thread = None
        self._stop = threading.Event()
        self._lock = threading.Lock()

    @property
    def plugged(self):
        return self._master is not None

    def plug(self):
        with self._lock:
            if self._master is not None:
                return
            master, slave = os.openpty()
            tty.setraw(slave)      # no echo, no line discipline before the driver configures it
            tmp = "%s.%d.tmp" % (self.link_path, os.getpid())
            if os.path.lexists(tmp):
                os.unlink(tmp)
            os.symlink(os.ttyname(slave), tmp)
            os.rename(tmp, self.link_path)     # atomic: the driver never sees a half-made link
            self._master, self._slave = master, slave
            self._stop = threading.Event()
            self._thread = threading.Thread(target=self._serve, args=(master, self._stop), name="sim_pelco_pty")
            self._thread.daemon = True
            self._thread.start()
            self._log("simulated Pelco-D head on %s -> %s" % (self.link_path, os.ttyname(slave)))

    def unplug(self):
        with self._lock:
            if self._master is None:
                return
            self._stop.set()
            self._thread.join(1.0)
            if os.path.islink(self.link_path):
                os.unlink(self.link_path)
            for fd in (self._master, self._slave):
                os.close(fd)
            self._master = self._slave = None

    def _serve(self, master, stop):
        reader = pelco.FrameReader()
        while not stop.is_set():
            ready, _, _ = select.select([master], [], [], 0.05)
            if not ready:
                continue
            try:
                data = os.read(master, 4096)
            except OSError:
                continue          # no slave open yet: EIO until the driver opens the port
            for frame in reader.feed(data):
                reply = self.head.handle(frame)
                if reply:
                    try:
                        os.write(master, reply)
                    except OSError as err:
                        self._log("simulated head write failed: %s" % err)
