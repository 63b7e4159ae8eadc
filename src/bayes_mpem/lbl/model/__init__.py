"""The LBL range model: what a beacon's ranges are predicted to be, and how likely they are."""
