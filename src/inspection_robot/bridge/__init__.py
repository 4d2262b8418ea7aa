"""Backend link: a rosbridge-v2-compatible websocket bridge (protocol, codec, transport)."""
