"""Test node: publishes UHState on ``state`` (relative name) and listens on ``command``.

Built like the project's nodes (Jazzy main() shape through ``rt.run_node``), so the tests exercise a
real entry point: ``python -m tests.helpers_runtime.talker --ros-args -r __ns:=/uh3 -p uh_id:=3``.
"""
import sys

import uh_runtime as rt
from uh_runtime.messages import ActuatorCommand, UHState

#: QoS of ``state`` in this node; the tests check that discovery reports exactly this.
STATE_QOS = rt.QoSProfile(depth=7, reliability=rt.ReliabilityPolicy.RELIABLE,
                          durability=rt.DurabilityPolicy.VOLATILE)
#: QoS of ``command``.
COMMAND_QOS = rt.QoSProfile(depth=3, reliability=rt.ReliabilityPolicy.BEST_EFFORT)


class Talker(rt.Node):
    def __init__(self):
        super().__init__('talker')
        self.declare_parameter('uh_id', 1, rt.ParameterDescriptor(
            description='helicopter index', integer_range=[rt.IntegerRange(from_value=1, to_value=20)]))
        self.declare_parameter('rate', 50.0, rt.ParameterDescriptor(
            description='publication rate, Hz',
            floating_point_range=[rt.FloatingPointRange(from_value=1.0, to_value=1000.0)]))
        self.declare_parameter('frame_id', 'world', rt.ParameterDescriptor(read_only=True))
        self.declare_parameter('teardown_s', 0.0, rt.ParameterDescriptor(
            description='s that destroy_node takes (as a recorder finalising a bag)', read_only=True))
        self.uh_id = self.get_parameter('uh_id').value
        self.frame_id = self.get_parameter('frame_id').value
        self.step = 0
        self.pub = self.create_publisher(UHState, 'state', STATE_QOS)
        self.sub = self.create_subscription(ActuatorCommand, 'command', self.on_command, COMMAND_QOS)
        self.timer = self.create_timer(1.0 / self.get_parameter('rate').value, self.tick)
        self.get_logger().info(f'talker {self.get_fully_qualified_name()} publishing on {self.pub.topic_name}')

    def tick(self):
        msg = UHState()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self.frame_id
        msg.uh_id = self.uh_id
        msg.step = self.step
        msg.position.x = 1.5 * self.step
        msg.velocity.z = -2.25
        msg.euler.z = 0.125
        self.pub.publish(msg)
        self.step += 1

    def on_command(self, msg):
        self.get_logger().info(f'command step {msg.step}')

    def destroy_node(self):
        import time
        if self.has_parameter('teardown_s') and self.get_parameter('teardown_s').value > 0:
            time.sleep(float(self.get_parameter('teardown_s').value))
            print('teardown complete', file=sys.stderr, flush=True)
        return super().destroy_node()


def main(args=None):
    return rt.run_node(Talker, args)


if __name__ == '__main__':
    sys.exit(main(sys.argv))
