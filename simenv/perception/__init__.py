"""The room's perception: the online recognition loop, its protocol on unseen people and its
training."""
