"""Survey-in: locate a transponder from two-way travel times measured from a ship."""
