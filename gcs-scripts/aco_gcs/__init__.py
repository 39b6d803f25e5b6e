"""Ground-station scripts for the ACO SITL (`sitl run`): pymavlink and MAVSDK-Python clients that fly it
the way a user scripts a PX4 vehicle, every wait measured on the vehicle's clock. Each module is a
command (`aco-<name>`, or `python -m aco_gcs.<module>`); `link` holds what they share."""

__version__ = "0.1.0"
