"""What the XYΘ rig is commanded: pose sets, sweeps, and the campaign's plans by name."""
