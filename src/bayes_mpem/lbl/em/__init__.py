"""The two EMs of one beacon (paper, mixture), their result, path choice and Pol sensitivity."""
