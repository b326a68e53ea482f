"""Names uh_runtime puts on the wire, each defined once.

The DDS prefixes rmw gives a ROS topic (``/uh1/state`` is DDS topic ``rt/uh1/state``) and the
request and reply topics of a ROS service (``rq/<service>Request``, ``rr/<service>Reply``), as
rmw_cyclonedds_cpp names them; and the ROS topic on which the recorder reports how far it has
written (:mod:`uh_runtime.bags.recorder`; listed with its type and QoS in :mod:`uh_wire.topics`).
A leaf module: importing it loads nothing else.
"""

__all__ = ['ROS_TOPIC_PREFIX', 'REQUEST_PREFIX', 'REPLY_PREFIX', 'ROS_PREFIXES', 'RECORDER_PROGRESS_TOPIC']

#: Prefix rmw puts in front of a ROS topic name to get the DDS topic name.
ROS_TOPIC_PREFIX = 'rt'
#: Prefix of the DDS request topic of a ROS service.
REQUEST_PREFIX = 'rq'
#: Prefix of the DDS reply topic of a ROS service.
REPLY_PREFIX = 'rr'
#: Every prefix of a DDS topic that belongs to the ROS graph.
ROS_PREFIXES = (ROS_TOPIC_PREFIX, REQUEST_PREFIX, REPLY_PREFIX)

#: ROS topic of the recorder's progress: the sim time up to which every per-step topic is in the bag.
RECORDER_PROGRESS_TOPIC = '/recorder/progress'
