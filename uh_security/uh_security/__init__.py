"""Secure mode of a team: DDS Security whose access control follows the communication graph (docs/security.md).

- :mod:`.policy`: the pure part: from a scenario and the run's node table to each node's allow lists
  (ROS names and their DDS names), the ROS 2 access-control policy XML and the DDS permissions and
  governance documents;
- :mod:`.keystore`: the CA, one identity per node and the signed documents, in sros2's keystore layout;
- :mod:`.cli`: ``uh-security create --scenario S --keystore DIR``.
"""
