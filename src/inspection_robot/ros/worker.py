"""One worker thread per request stream, so subscriber callbacks only hand requests over.

Topic commands (device cmd topics, voice, preset recording, meter reading, virtual obstacles,
preset_rotate) may take seconds; rospy runs one callback thread per subscription, so doing the
work in the callback would stall that topic. Requests run in arrival order; a full queue refuses
the newest request at once instead of delaying every later one.
"""
import queue
import threading
import traceback

import rospy


class RequestWorker(object):
    """Runs ``handle(request)`` for each submitted request, in order, on one daemon thread.

    ``submit`` never blocks: with ``maxsize`` requests already waiting, ``refuse(request)`` is
    called in the caller's thread so the sender hears at once that it was dropped.
    """

    def __init__(self, name, handle, refuse, maxsize):
        self._name = name
        self._handle = handle
        self._refuse = refuse
        self._queue = queue.Queue(maxsize=maxsize)
        self._thread = threading.Thread(target=self._run, name=name)
        self._thread.daemon = True
        self._thread.start()

    def submit(self, request):
        try:
            self._queue.put_nowait(request)
        except queue.Full:
            rospy.logwarn_throttle(1.0, "%s: queue full (%d waiting), refusing a request"
                                   % (self._name, self._queue.maxsize))
            self._refuse(request)

    def _run(self):
        while not rospy.is_shutdown():
            try:
                request = self._queue.get(timeout=0.2)
            except queue.Empty:
                continue
            try:
                self._handle(request)
            except Exception as err:  # boundary: the worker outlives any one request
                rospy.logerr("%s: request raised %s\n%s" % (self._name, err, traceback.format_exc()))
