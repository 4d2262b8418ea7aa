"""The service half of a protocol Session: a client's calls of ROS services (and of the bridge's own
rosapi services), the services a client provides to ROS, and their requests and responses.

Kept apart from protocol.py, which holds a client's state, dispatch, authentication and teardown:
:class:`ServiceOps` is a mixin of protocol.Session; its methods use the session's backend, rosapi,
send, call_later, status and surface check (``_allowed``), and its ``_services`` and
``_pending_requests``.
"""
from inspection_robot.bridge.ops import COMPRESSIONS, BridgeError, compact_json


class ServiceOps(object):
    """Service calls in both directions for one client (a mixin of protocol.Session)."""

    # ------------------------------------------------------------------ services
    def _op_call_service(self, args, mid):
        service = args["service"]
        fragment_size, compression, timeout = args["fragment_size"], args["compression"], args["timeout"]
        if compression not in COMPRESSIONS:
            raise BridgeError("compression must be one of %s" % ", ".join(COMPRESSIONS))
        if timeout is not None and not (timeout > 0 and timeout < 1e9):
            raise BridgeError("timeout must be a positive number of seconds, not %r" % (timeout,))
        state = {"answered": False, "timer": None}

        def done(ok, values):
            if self._closed or state["answered"]:
                return
            state["answered"] = True
            if state["timer"] is not None:
                state["timer"].cancel()
            message = {"op": "service_response", "service": service, "values": values, "result": ok}
            if mid is not None:
                message["id"] = mid
            if not ok:
                self.status("error", "call_service: %s" % values, mid, "call_service")
            self._send_json(message, fragment_size, compression)

        call_args = args["args"] if args["args"] is not None else {}
        refusal = self._call_refusal(service, call_args)
        if refusal:   # answered like a failed call: roslibjs/roslibpy see the reason as the call's error
            done(False, refusal)
            return
        if timeout is not None:
            # as rosbridge (ros2 branch): past the timeout the call fails; a late response is dropped
            state["timer"] = self._call_later(timeout, lambda: done(
                False, "Timeout exceeded while waiting for service %s (%g s)" % (service, timeout)))
        try:
            if self._rosapi is not None and self._rosapi.handles(service):
                visible = None
                if self.surface is not None:
                    visible = lambda name: self.surface.allows("params", name)  # noqa: E731
                self._backend.run_blocking(lambda: self._rosapi.call(service, call_args, visible), done)
            else:
                self._backend.call_service(service, call_args, args["type"], timeout, done)
        except Exception:
            state["answered"] = True  # the error status answers the call
            if state["timer"] is not None:
                state["timer"].cancel()
            raise

    def _call_refusal(self, service, call_args):
        """Why this client's role may not make this call (the service, or the parameter a rosapi call
        names), or None."""
        try:
            self._allowed("call", service)
            if self._rosapi is not None and self._rosapi.handles(service):
                name = self._rosapi.param_name(service, call_args)
                if name is not None:
                    self._allowed("params", name)
        except BridgeError as exc:
            return str(exc)
        return None

    def _op_advertise_service(self, args, mid):
        service = args["service"]
        if self.surface is not None and not self.surface.open:
            raise BridgeError("advertising services is refused: no role offers services to the robot (rule "
                              "%s.advertise_service; docs/interface.md, Backend surface)" % self.surface.role)
        if self._rosapi is not None and self._rosapi.handles(service):
            raise BridgeError("Service %s is provided by the bridge itself" % service)
        if service in self._services:
            self._backend.unadvertise_service(self, service)
            self._services.discard(service)
        self._backend.advertise_service(self, service, args["type"])
        self._services.add(service)

    def _op_unadvertise_service(self, args, mid):
        service = args["service"]
        if service not in self._services:
            raise BridgeError("Service %s is not advertised by this client" % service, "warning")
        self._services.discard(service)
        self._backend.unadvertise_service(self, service)
        for request_id, (svc, callback) in list(self._pending_requests.items()):
            if svc == service:
                del self._pending_requests[request_id]
                callback(False, "service %s was unadvertised" % service)

    def request(self, service, args, callback):
        """ROS calls a service this client provides: forward it; ``callback(result, values)`` later."""
        if self._closed or service not in self._services:
            callback(False, "client %s does not provide %s" % (self.client_id, service))
            return None
        self._request_counter += 1
        request_id = "service_request:%s:%d" % (service, self._request_counter)
        self._pending_requests[request_id] = (service, callback)
        self._send([compact_json({"op": "call_service", "id": request_id, "service": service, "args": args})],
                   None, None, False)
        return request_id

    def cancel_request(self, request_id):
        """Forget a forwarded request (it timed out on the ROS side)."""
        self._pending_requests.pop(request_id, None)

    def _op_service_response(self, args, mid):
        entry = self._pending_requests.pop(mid, None) if mid is not None else None
        if entry is None:
            raise BridgeError("No pending call of service %s with id %s" % (args["service"], mid))
        values = args["values"]
        if args["result"] and not isinstance(values, dict):
            if values is not None:
                entry[1](False, "the response values of %s must be an object" % args["service"])
                raise BridgeError("the values of a successful response must be an object")
            values = {}
        entry[1](args["result"], values)
