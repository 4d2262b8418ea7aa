"""rosapi's services, answered inside the bridge (no rosapi node or srv types needed).

``call_service`` on ``/rosapi/<name>`` (or ``rosapi/<name>``) is answered here with rosapi's
request/response JSON shapes, so roslibjs/roslibpy helpers (get_topics, get_params,
get_message_details...) work unchanged. ``/rosapi/*`` names appear in ``services`` and
``service_type`` reports ``rosapi/<Type>`` as the rosapi node would. The ROS graph, parameter
server and clock come from a ``graph`` object (bridge.ros_backend.RosGraph) and message classes from a
TypeSupport, so this module needs no rospy.
"""
import json

from inspection_robot.bridge.codec import PRIMITIVE_TYPES, TIME_TYPES, split_array

PREFIX = "/rosapi/"
PARAM_SERVICES = ("get_param", "has_param", "search_param", "set_param", "delete_param")
ACTION_SUFFIXES = ("goal", "cancel", "status", "feedback", "result")


class RosApiError(ValueError):
    """A rosapi request that cannot be answered."""


def _text_arg(args, name, default=""):
    value = args.get(name, default)
    if not isinstance(value, str):
        raise RosApiError("field %s must be a string" % name)
    return value


def typedef_of(cls):
    """rosapi's TypeDef of a message class: fieldnames, fieldtypes, fieldarraylen, examples, constants."""
    fieldtypes, arraylens, examples = [], [], []
    instance = cls()
    for name, slot_type in zip(cls.__slots__, cls._slot_types):
        base, length = split_array(slot_type)
        arraylens.append(-1 if length is None else length)
        fieldtypes.append(base)
        if length is not None:
            examples.append("[]")
        elif base in PRIMITIVE_TYPES:
            examples.append(str(getattr(instance, name)))
        else:
            examples.append("{}")
    constnames, constvalues = [], []
    for member in sorted(dir(cls)):
        if member.startswith("_") or member in cls.__slots__:
            continue
        value = getattr(cls, member)
        if callable(value) or isinstance(value, property):
            continue
        constnames.append(member)
        constvalues.append(str(value))
    return {"type": cls._type, "fieldnames": list(cls.__slots__), "fieldtypes": fieldtypes,
            "fieldarraylen": arraylens, "examples": examples, "constnames": constnames, "constvalues": constvalues}


def time_typedef(kind):
    return {"type": kind, "fieldnames": ["secs", "nsecs"], "fieldtypes": ["int32", "int32"],
            "fieldarraylen": [-1, -1], "examples": ["0", "0"], "constnames": [], "constvalues": []}


def typedefs_recursive(cls, message_class):
    """The TypeDefs of ``cls`` and of every type nested in it, each once, outermost first."""
    out, seen, todo = [], set(), [cls]
    while todo:
        current = todo.pop(0)
        if isinstance(current, str):
            out.append(time_typedef(current))
            continue
        typedef = typedef_of(current)
        out.append(typedef)
        for field_type in typedef["fieldtypes"]:
            if field_type in seen or field_type in PRIMITIVE_TYPES:
                continue
            seen.add(field_type)
            todo.append(field_type if field_type in TIME_TYPES else message_class(field_type))
    return out


class RosApi(object):
    """Dispatches ``/rosapi/<name>`` calls; ``call`` runs in a worker thread (it may block on ROS)."""

    def __init__(self, graph, types):
        self._graph = graph
        self._types = types
        self._handlers = {
            "topics": ("Topics", self.topics),
            "topics_for_type": ("TopicsForType", self.topics_for_type),
            "topic_type": ("TopicType", self.topic_type),
            "services": ("Services", self.services),
            "services_for_type": ("ServicesForType", self.services_for_type),
            "service_type": ("ServiceType", self.service_type),
            "nodes": ("Nodes", self.nodes),
            "node_details": ("NodeDetails", self.node_details),
            "publishers": ("Publishers", self.publishers),
            "subscribers": ("Subscribers", self.subscribers),
            "service_providers": ("ServiceProviders", self.service_providers),
            "service_node": ("ServiceNode", self.service_node),
            "message_details": ("MessageDetails", self.message_details),
            "service_request_details": ("ServiceRequestDetails", self.service_request_details),
            "service_response_details": ("ServiceResponseDetails", self.service_response_details),
            "get_param": ("GetParam", self.get_param),
            "set_param": ("SetParam", self.set_param),
            "has_param": ("HasParam", self.has_param),
            "delete_param": ("DeleteParam", self.delete_param),
            "search_param": ("SearchParam", self.search_param),
            "get_param_names": ("GetParamNames", self.get_param_names),
            "get_time": ("GetTime", self.get_time),
            "action_servers": ("GetActionServers", self.action_servers),
        }

    @staticmethod
    def _short_name(service):
        name = service if service.startswith("/") else "/" + service
        return name[len(PREFIX):] if name.startswith(PREFIX) else None

    def handles(self, service):
        return self._short_name(service) in self._handlers

    def names(self):
        return sorted(PREFIX + name for name in self._handlers)

    def type_of(self, service):
        short = self._short_name(service)
        return "rosapi/" + self._handlers[short][0] if short in self._handlers else None

    @staticmethod
    def _request(args):
        if isinstance(args, list):
            args = {} if not args else args[0] if isinstance(args[0], dict) else None
            if args is None:
                raise RosApiError("rosapi requests take an object of named fields")
        return args

    def param_name(self, service, args):
        """The parameter a get_param/has_param/search_param/set_param/delete_param request names (None for
        other services or a request without one), for the caller's access check before the call."""
        if self._short_name(service) not in PARAM_SERVICES:
            return None
        try:
            name = self._request(args).get("name")
        except (RosApiError, AttributeError):
            return None
        return name if isinstance(name, str) else None

    def call(self, service, args, param_visible=None):
        """The response dict of rosapi service ``service`` for request ``args`` (dict or list).
        ``param_visible(name)``: False hides a parameter from get_param_names (None: all shown)."""
        args = self._request(args)
        short = self._short_name(service)
        result = self._handlers[short][1](args)
        if short == "get_param_names" and param_visible is not None:
            result["names"] = [n for n in result["names"] if param_visible(n)]
        return result

    # ---------------------------------------------------------------- graph
    def topics(self, args):
        pairs = sorted(self._graph.topic_types())
        return {"topics": [t for t, _ in pairs], "types": [ty for _, ty in pairs]}

    def topics_for_type(self, args):
        wanted = _text_arg(args, "type")
        return {"topics": sorted(t for t, ty in self._graph.topic_types() if ty == wanted)}

    def topic_type(self, args):
        topic = self._graph.resolve(_text_arg(args, "topic"))
        return {"type": dict(self._graph.topic_types()).get(topic, "")}

    def _all_services(self):
        _pubs, _subs, services = self._graph.system_state()
        return sorted(set(name for name, _nodes in services) | set(self.names()))

    def services(self, args):
        return {"services": self._all_services()}

    def _service_type(self, service):
        return self.type_of(service) or self._graph.service_type(service) or ""

    def services_for_type(self, args):
        wanted = _text_arg(args, "type")
        return {"services": [s for s in self._all_services() if self._service_type(s) == wanted]}

    def service_type(self, args):
        return {"type": self._service_type(self._graph.resolve(_text_arg(args, "service")))}

    def nodes(self, args):
        names = set()
        for group in self._graph.system_state():
            for _name, nodes in group:
                names.update(nodes)
        return {"nodes": sorted(names)}

    def node_details(self, args):
        node = self._graph.resolve(_text_arg(args, "node"))
        pubs, subs, services = self._graph.system_state()
        return {"subscribing": sorted(n for n, nodes in subs if node in nodes),
                "publishing": sorted(n for n, nodes in pubs if node in nodes),
                "services": sorted(n for n, nodes in services if node in nodes)}

    def _nodes_of(self, group_index, name):
        name = self._graph.resolve(name)
        group = self._graph.system_state()[group_index]
        return sorted(next((nodes for n, nodes in group if n == name), []))

    def publishers(self, args):
        return {"publishers": self._nodes_of(0, _text_arg(args, "topic"))}

    def subscribers(self, args):
        return {"subscribers": self._nodes_of(1, _text_arg(args, "topic"))}

    def service_providers(self, args):
        wanted = _text_arg(args, "service")
        return {"providers": [s for s in self._all_services() if self._service_type(s) == wanted]}

    def service_node(self, args):
        nodes = self._nodes_of(2, _text_arg(args, "service"))
        return {"node": nodes[0] if nodes else ""}

    def action_servers(self, args):
        topics = dict(self._graph.topic_types())
        servers = set()
        for topic, topic_type in topics.items():
            if topic.endswith("/goal") and topic_type.endswith("ActionGoal"):
                base = topic[:-len("/goal")]
                if all(base + "/" + s in topics for s in ACTION_SUFFIXES):
                    servers.add(base)
        return {"action_servers": sorted(servers)}

    # ---------------------------------------------------------------- types
    def message_details(self, args):
        return {"typedefs": typedefs_recursive(self._types.message_class(_text_arg(args, "type")),
                                               self._types.message_class)}

    def service_request_details(self, args):
        srv = self._types.service_class(_text_arg(args, "type"))
        return {"typedefs": typedefs_recursive(srv._request_class, self._types.message_class)}

    def service_response_details(self, args):
        srv = self._types.service_class(_text_arg(args, "type"))
        return {"typedefs": typedefs_recursive(srv._response_class, self._types.message_class)}

    # ---------------------------------------------------------------- parameters
    def get_param(self, args):
        name, default_text = _text_arg(args, "name"), _text_arg(args, "default")
        default = None
        if default_text:
            try:
                default = json.loads(default_text)
            except ValueError:
                default = default_text
        return {"value": json.dumps(self._graph.get_param(name, default))}

    def set_param(self, args):
        name, value_text = _text_arg(args, "name"), _text_arg(args, "value")
        try:
            value = json.loads(value_text)
        except ValueError:
            raise RosApiError("the value argument to set_param must be a JSON-formatted string")
        self._graph.set_param(name, value)
        return {}

    def has_param(self, args):
        return {"exists": bool(self._graph.has_param(_text_arg(args, "name")))}

    def delete_param(self, args):
        name = _text_arg(args, "name")
        if self._graph.has_param(name):
            self._graph.delete_param(name)
        return {}

    def search_param(self, args):
        return {"global_name": self._graph.search_param(_text_arg(args, "name")) or ""}

    def get_param_names(self, args):
        return {"names": sorted(self._graph.param_names())}

    def get_time(self, args):
        secs, nsecs = self._graph.now()
        return {"time": {"secs": secs, "nsecs": nsecs}}
