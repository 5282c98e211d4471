"""What the nano rig is commanded: sequences, the campaign's plans, designed training."""
