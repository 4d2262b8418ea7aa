"""Pan/tilt head: Pelco-D protocol, serial driver and the cloud_terrace command logic."""
