"""The Stream Processor (thesis 2.3.2, 4.4): topics → merged fluents → synchronised states."""

# rosbags' standard message definitions, by name (--typestore): here, so the CLI's help
# names them without importing the readers.
TYPESTORES = (
    "ros1_noetic",
    "ros2_foxy",
    "ros2_galactic",
    "ros2_humble",
    "ros2_iron",
    "ros2_jazzy",
    "ros2_kilted",
    "latest",
)
