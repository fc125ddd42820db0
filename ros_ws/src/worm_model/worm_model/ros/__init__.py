"""ROS 2 shell support shared by every node of the project: QoS profiles (``qos``), parameter
declaration with descriptions and ranges (``parameters``), /diagnostics (``diagnostics``),
subscriptions to commands that every publisher reaches and a late joiner still gets
(``commands``), one node per process with a clean shutdown (``lifecycle``) and a teardown
with a deadline (``teardown``), the ament prefixes and executables (``ament``), and helpers
for tests over DDS (``testing``), two hosts on one machine, network namespaces whose link a
test can cut (``two_hosts``), and a stand-in robot that plays joint states as
joint_state_broadcaster publishes them (``joint_state_player``)."""
