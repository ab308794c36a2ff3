"""The room's perception and its agent: the online recognition loop and its one decision rule,
the room's agent (perceive -> decide -> act), the loop's protocol on unseen people and its
training."""
