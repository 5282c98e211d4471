"""What the hexapod is commanded: poses, the campaign's plans by name, the designed plan."""
