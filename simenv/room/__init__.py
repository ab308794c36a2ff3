"""The virtual room: its physical world, scenarios, furniture and recorded sessions."""
