"""Pan/tilt head driver: the interface cloud_terrace uses, and its Pelco-D implementation on pyserial.

The port is opened with ``serial.serial_for_url``, so a device (/dev/ttyUSB0), a pseudo-terminal
(the simulator's), ``socket://host:port`` and ``loop://`` all work unchanged. One reader thread
owns reading and reconnecting: it feeds bytes to :class:`~inspection_robot.ptz.pelco.FrameReader`
(resync on 0xFF), hands query replies to waiting callers, and when the port fails or vanishes
closes it and reopens it with exponential backoff. Writers send whole frames under a lock (the
pyserial ``threaded`` pattern: one reader thread, writes from callers). Angles in this API are
STANDARD integer hundredths of a degree; the physical conversion happens here, at the wire.
"""
import collections
import threading

import serial

from inspection_robot.drivers import not_fitted_class, not_fitted_reason
from inspection_robot.ptz import pelco


class HeadError(Exception):
    """The head could not carry out a request (not connected, no reply); message = reason."""


class PanTiltHead(object):
    """Interface of a pan/tilt head. Angles: standard hundredths of a degree (ints)."""

    def set_pan(self, pan_centi):
        raise NotImplementedError

    def set_tilt(self, tilt_centi):
        raise NotImplementedError

    def query_pan(self):
        raise NotImplementedError

    def query_tilt(self):
        raise NotImplementedError

    def move(self, pan_direction, tilt_direction, pan_speed, tilt_speed):
        """pan_direction: +1 left (CCW), -1 right, 0; tilt_direction: +1 down, -1 up, 0."""
        raise NotImplementedError

    def stop(self):
        raise NotImplementedError

    def set_wiper(self, on):
        raise NotImplementedError

    def set_lamp(self, on):
        raise NotImplementedError

    @property
    def connected(self):
        raise NotImplementedError

    def close(self):
        pass


class PelcoHead(PanTiltHead):
    """A Pelco-D head on a serial link.

    ``port``: a pyserial URL or device path; ``reply_timeout`` (s): how long a query waits;
    ``backoff`` (s): (first, max) delay between reopen attempts; ``opener``: for tests.
    """

    def __init__(self, port, baudrate=9600, address=pelco.DEFAULT_ADDRESS, reply_timeout=0.3,
                 backoff=(0.1, 2.0), opener=None, logger=None):
        if not 0 <= int(address) <= 0xFF:
            raise ValueError("Pelco-D address must be 0..255, got %r" % (address,))
        self.port = port
        self.baudrate = int(baudrate)
        self.address = int(address)
        self.reply_timeout = float(reply_timeout)
        self._backoff = (float(backoff[0]), float(backoff[1]))
        self._opener = opener or self._open_serial
        self._log = logger or (lambda text: None)
        self._serial = None
        self._write_lock = threading.Lock()
        self._state_lock = threading.Lock()
        self._waiters = collections.defaultdict(collections.deque)   # reply cmd2 -> deque of slots
        self._reader = pelco.FrameReader(accept=self._is_reply)
        self._stop = threading.Event()
        self._connected = threading.Event()
        self.reconnects = 0
        self.last_error = ""
        self._thread = threading.Thread(target=self._run, name="pelco_reader %s" % port)
        self._thread.daemon = True
        self._thread.start()

    # --- link ---------------------------------------------------------------------------
    def _open_serial(self):
        return serial.serial_for_url(self.port, baudrate=self.baudrate, timeout=0.2,
                                     write_timeout=0.5)

    @property
    def connected(self):
        return self._connected.is_set()

    def wait_connected(self, timeout):
        return self._connected.wait(timeout)

    @property
    def stats(self):
        return {"frames": self._reader.frames, "bad_checksums": self._reader.bad_checksums,
                "discarded_bytes": self._reader.discarded_bytes, "reconnects": self.reconnects}

    def close(self):
        self._stop.set()
        link = self._serial
        if link is not None:
            try:
                link.cancel_read()
            except (AttributeError, serial.SerialException, OSError):
                pass
        self._thread.join(2.0)
        self._drop_link("closed")

    def _run(self):
        delay = self._backoff[0]
        while not self._stop.is_set():
            if self._serial is None:
                try:
                    link = self._opener()
                except (serial.SerialException, OSError, ValueError) as err:
                    self.last_error = "cannot open %s: %s" % (self.port, err)
                    self._stop.wait(delay)
                    delay = min(delay * 2.0, self._backoff[1])
                    continue
                with self._write_lock:
                    self._serial = link
                self.reconnects += 1
                delay = self._backoff[0]
                self._connected.set()
                self._log("pan/tilt head port %s open" % self.port)
            try:
                data = self._serial.read(max(1, self._serial.in_waiting))
            except (serial.SerialException, OSError, TypeError, AttributeError) as err:
                # TypeError/AttributeError: pyserial's read() on a port closed under it
                self._drop_link("port %s failed: %s" % (self.port, err))
                continue
            if data:
                for frame in self._reader.feed(data):
                    self._dispatch(frame)

    def _drop_link(self, reason):
        was_connected = self._connected.is_set()
        self._connected.clear()
        with self._write_lock:
            link, self._serial = self._serial, None
        if link is not None:
            try:
                link.close()
            except (serial.SerialException, OSError):
                pass
        if was_connected:
            self.last_error = reason
            self._log(reason)
        with self._state_lock:
            waiting = [slot for slots in self._waiters.values() for slot in slots]
            self._waiters.clear()
        for slot in waiting:
            slot["error"] = reason
            slot["event"].set()

    def _is_reply(self, frame):
        return frame.address == self.address and frame.cmd1 == 0 and frame.cmd2 in (pelco.REPLY_PAN, pelco.REPLY_TILT)

    def _dispatch(self, frame):
        with self._state_lock:
            slots = self._waiters.get(frame.cmd2)
            slot = slots.popleft() if slots else None
        if slot is not None:
            slot["frame"] = frame
            slot["event"].set()

    def _write(self, frame_bytes):
        with self._write_lock:
            link = self._serial
            if link is None:
                raise HeadError("pan/tilt head not connected (%s)" % (self.last_error or self.port))
            try:
                link.write(frame_bytes)
                link.flush()
                return
            except (serial.SerialException, OSError) as err:
                reason = "pan/tilt head write failed on %s: %s" % (self.port, err)
        # A dead link is dropped at once (not only when the reader notices), so `connected`
        # is false until the port really reopens and the next command does not reuse it.
        self._drop_link(reason)
        raise HeadError(reason)

    def _query(self, frame_bytes, reply_cmd):
        slot = {"event": threading.Event(), "frame": None, "error": None}
        with self._state_lock:
            self._waiters[reply_cmd].append(slot)
        try:
            self._write(frame_bytes)
        except HeadError:
            self._forget(reply_cmd, slot)
            raise
        if not slot["event"].wait(self.reply_timeout):
            self._forget(reply_cmd, slot)
            raise HeadError("no reply from pan/tilt head on %s within %.2f s" % (self.port, self.reply_timeout))
        if slot["error"]:
            raise HeadError("pan/tilt head lost: %s" % slot["error"])
        return slot["frame"]

    def _forget(self, reply_cmd, slot):
        with self._state_lock:
            try:
                self._waiters[reply_cmd].remove(slot)
            except ValueError:
                pass

    # --- commands -------------------------------------------------------------------------
    def set_pan(self, pan_centi):
        self._write(pelco.set_pan(self.address, pelco.pan_standard_to_physical(pan_centi)))

    def set_tilt(self, tilt_centi):
        self._write(pelco.set_tilt(self.address, pelco.tilt_standard_to_physical(tilt_centi)))

    def query_pan(self):
        frame = self._query(pelco.query_pan(self.address), pelco.REPLY_PAN)
        try:
            return pelco.pan_physical_to_standard(frame.data)
        except ValueError as err:
            raise HeadError("pan/tilt head sent an invalid pan: %s" % err)

    def query_tilt(self):
        frame = self._query(pelco.query_tilt(self.address), pelco.REPLY_TILT)
        try:
            return pelco.tilt_physical_to_standard(frame.data)
        except ValueError as err:
            raise HeadError("pan/tilt head sent an invalid tilt: %s" % err)

    def move(self, pan_direction, tilt_direction, pan_speed, tilt_speed):
        bits = 0
        if pan_direction > 0:
            bits |= pelco.DIR_LEFT
        elif pan_direction < 0:
            bits |= pelco.DIR_RIGHT
        if tilt_direction > 0:
            bits |= pelco.DIR_DOWN
        elif tilt_direction < 0:
            bits |= pelco.DIR_UP
        self._write(pelco.move(self.address, bits, pan_speed if pan_direction else 0,
                               tilt_speed if tilt_direction else 0))

    def stop(self):
        self._write(pelco.stop(self.address))

    def set_wiper(self, on):
        self._write(pelco.wiper(self.address, on))

    def set_lamp(self, on):
        self._write(pelco.lamp(self.address, on))


NoHead = not_fitted_class(PanTiltHead, HeadError, "head", stop=lambda self: None, stats={}, port="none",
                          last_error=not_fitted_reason("head"))
"""``~driver: none``: every request fails with the reason; stop (shutdown) passes."""
