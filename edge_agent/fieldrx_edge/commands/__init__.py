"""What each ``fieldrx-edge`` sub-command does (``cli`` only parses the arguments)."""
