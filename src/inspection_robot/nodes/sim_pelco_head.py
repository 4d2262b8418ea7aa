"""sim_pelco_head: a simulated Pelco-D pan/tilt head on a pseudo-terminal (inspection_robot.sim.pelco_head).

It creates a pty and points the symlink ~link at its slave side; cloud_terrace opens that path
as its serial port (its ~port), so the real driver code runs against the simulated bytes.

Services:    ~sim_control (ControlService), simulator-only:
               fault   data none|silence|bad_checksum|garbage
               unplug  the port vanishes (pty closed, link removed); replug: a new pty, same link
               get_state -> "pan,tilt,wiper,lamp" (standard hundredths of a degree, 0|1)
               get_motion -> "moving" | "still" (whether the last move frame still drives the head)
Parameters:  config/sim_pelco_head.yaml: every setting, its default and meaning (read through ros.node.NodeSettings)
             (the launch passes a unique ~link)
"""
import rospy

from inspection_robot.command import CommandError, CommandTable, parse_choice
from inspection_robot.ptz import pelco
from inspection_robot.ros.node import NodeSettings, init_node
from inspection_robot.sim.pelco_head import FAULTS, PtyPelcoServer, SimPelcoHead
from inspection_robot.ros.twin import serve_table


class SimPelcoHeadNode(object):
    def __init__(self, server):
        self._server = server
        self._table = CommandTable({"fault": self._fault, "unplug": self._unplug, "replug": self._replug,
                                    "get_state": self._get_state, "get_motion": self._get_motion})
        self._service = serve_table("~sim_control", self._table)

    def _fault(self, data):
        self._server.head.fault = parse_choice(data, "fault", FAULTS)

    def _unplug(self, _data):
        self._server.unplug()

    def _replug(self, _data):
        try:
            self._server.plug()
        except OSError as err:
            raise CommandError("cannot create the pty: %s" % err)

    def _get_state(self, _data):
        pan, tilt, wiper, lamp = self._server.head.state()
        return "%d,%d,%d,%d" % (pan, tilt, int(wiper), int(lamp))

    def _get_motion(self, _data):
        return "moving" if self._server.head.moving() else "still"


def main():
    init_node("sim_pelco_head")
    settings = NodeSettings("sim_pelco_head")
    link = settings.get("~link")
    head = SimPelcoHead(address=settings.get("~address"),
                        max_speed_deg_s=settings.get("~max_speed_deg_s"),
                        position_speed_deg_s=settings.get("~position_speed_deg_s"),
                        tilt_limits_centi=(pelco.degrees_to_centi(settings.get("~tilt_min_deg")),
                                           pelco.degrees_to_centi(settings.get("~tilt_max_deg"))))
    server = PtyPelcoServer(head, link, logger=rospy.loginfo)
    server.plug()
    rospy.on_shutdown(server.unplug)
    SimPelcoHeadNode(server)
    rospy.spin()
