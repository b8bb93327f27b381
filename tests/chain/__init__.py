"""The chain's MQTT broker (issue 34): restaurants ship their events to hq over Mosquitto."""
