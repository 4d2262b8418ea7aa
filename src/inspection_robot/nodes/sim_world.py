"""sim_world: owner of the simulated yard's run-time values (gauge readings, lamps, switches, hot spots).

Services:    sim/set_world_value (ControlService): cmd = face or hot spot id, foreign/<name>, light or day,
             data = value
             (gauge: number within its range; lamp: on|off; switch: open|closed; hot spot: degC);
             cmd = foreign/<name>: drops a foreign object (data "equipment,side,u,v,w,h", m, a
             plate 8 cm in front of that side; "" removes it);
             ack success with the canonical value, or failed with the reason
             sim/get_world_value (ControlService): cmd = id; data = the current value
Publishes:   sim/world_state (GeneralTopic, latched): JSON {"values": {id: value}} on every change;
             the simulated camera and thermal imager apply it to their renderers
Parameters:  ~world_file (path, required): the world YAML (config/sim_world.yaml)
"""
import json

import rospy

from inspection_robot.command import failed, success
from inspection_robot.msg import GeneralTopic
from inspection_robot.ros.node import init_node
from inspection_robot.sim.world import World, WorldError
from inspection_robot.ros.twin import control_response
from inspection_robot.srv import ControlService


class SimWorldNode(object):
    def __init__(self, world):
        self._world = world
        self._pub = rospy.Publisher("sim/world_state", GeneralTopic, queue_size=10, latch=True)
        self._set = rospy.Service("sim/set_world_value", ControlService, self._on_set)
        self._get = rospy.Service("sim/get_world_value", ControlService, self._on_get)
        self._publish()

    def _publish(self):
        msg = GeneralTopic(sender="sim_world", data=json.dumps({"values": self._world.values()}, sort_keys=True))
        msg.header.stamp = rospy.Time.now()
        self._pub.publish(msg)

    def _on_set(self, req):
        try:
            value = self._world.set_value(req.cmd, req.data)
        except WorldError as err:
            reply = failed(err)
        else:
            self._publish()
            reply = success(value)
        return control_response(req, reply)

    def _on_get(self, req):
        try:
            reply = success(self._world.get_value(req.cmd))
        except WorldError as err:
            reply = failed(err)
        return control_response(req, reply)


def main():
    init_node("sim_world")
    SimWorldNode(World.load(rospy.get_param("~world_file")))
    rospy.spin()
