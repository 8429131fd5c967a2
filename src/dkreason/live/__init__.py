"""Live monitoring over Zenoh, a module per protocol and concern.

Shared:      session.py  a Zenoh session opened (endpoints, config file); how callbacks run
             inbox.py    events from zenoh's threads to a monitor's loop
             loop.py     the run loop both live monitors share, and their live stream source
             change.py   what a live monitor says besides verdicts and violations
The federation (`dkreason serve`, `dkreason monitor --live`):
             wire.py     its wire format: key expressions, the payload codec
             signing.py  Ed25519-signed samples and knowledge replies (a nonce per run,
                         a challenge per query), the trusted keys, checked to fail closed
             serve.py    a platform node
             monitor.py  the monitor that finds the nodes (LiveMonitor)
ROS 2 (`dkreason monitor --ros2`):
             rmw.py      rmw_zenoh's and zenoh-bridge-ros2dds' keys, tokens and attachments
             ros2.py     the monitor: discovery, binding, CDR decoding (Ros2Monitor)
             ros2node.py ROS 2 publishers from Python, in rmw_zenoh's format
Either monitor's output:
             publish.py  verdicts and violations published (`--publish-verdicts`)
             record.py   a live run recorded (`--record`)
For tests, examples and benchmarks only (production code never imports it):
             testing.py  a recording replayed as live ROS 2 robots
"""
