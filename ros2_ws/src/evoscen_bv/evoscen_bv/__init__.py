"""evoscen background-vehicle driver models (level-0 traffic now; learned social drivers later)."""
