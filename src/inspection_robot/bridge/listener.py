"""The listening socket's guard at the process's file-descriptor limit (:class:`GuardedListener`).

Kept apart from server.py: a socket subclass on the accept path only, the one place the bridge
handles EMFILE / ENFILE (issue #39, limits before trust); server.py wraps its bound sockets in it.
"""
import errno
import os
import socket

import tornado.ioloop

ACCEPT_PAUSE = 0.5  # s the listening socket is not polled when even a spare descriptor is gone


class GuardedListener(socket.socket):
    """A listening socket whose accept() refuses connections at the file-descriptor limit instead of failing.

    tornado's accept loop catches only BlockingIOError: an EMFILE / ENFILE went up to the event
    loop as a traceback, and the socket, still readable, was polled again at once (a busy loop at
    94 % CPU, ~5 MB/s of tracebacks). Here the error becomes a refusal: a spare descriptor is given
    up for a moment to accept the waiting connection and close it at once (the client sees the
    connection closed, not a hang), then BlockingIOError ends tornado's loop for this pass. Should
    even the spare be gone, the socket is not polled for ACCEPT_PAUSE s (IOLoop.update_handler).
    ``on_refused()`` is called for every refusal. Public APIs only (socket, IOLoop).
    """

    @classmethod
    def wrap(cls, sock, on_refused):
        listener = cls(sock.family, sock.type, sock.proto, fileno=sock.detach())
        listener.setblocking(False)
        listener.guard(on_refused)
        return listener

    def guard(self, on_refused):
        """Keep the spare descriptor and call ``on_refused()`` for every refusal from now on."""
        self._on_refused = on_refused
        self._spare = None
        self._reserve()

    def _reserve(self):
        try:
            self._spare = os.open(os.devnull, os.O_RDONLY)
        except OSError:
            self._spare = None

    def accept(self):
        try:
            return super(GuardedListener, self).accept()
        except OSError as exc:
            if exc.errno not in (errno.EMFILE, errno.ENFILE):
                raise
        self._on_refused()
        if self._spare is not None:
            os.close(self._spare)
            self._spare = None
            try:
                conn, _address = super(GuardedListener, self).accept()
                conn.close()
            except OSError:
                pass
            self._reserve()
        if self._spare is None:
            loop = tornado.ioloop.IOLoop.current()
            loop.update_handler(self, 0)
            loop.call_later(ACCEPT_PAUSE, self._resume)
        raise BlockingIOError(errno.EAGAIN, "connection refused at the file-descriptor limit")

    def _resume(self):
        if self.fileno() >= 0:
            if self._spare is None:
                self._reserve()
            tornado.ioloop.IOLoop.current().update_handler(self, tornado.ioloop.IOLoop.READ)

    def close(self):
        if getattr(self, "_spare", None) is not None:
            os.close(self._spare)
            self._spare = None
        super(GuardedListener, self).close()
