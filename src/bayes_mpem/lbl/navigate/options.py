"""The names of ``navigate``'s choices; imports nothing, so ``--help`` loads no numpy."""

#: What stands for the ranges' likelihood: the mixture, or a baseline's weights.
MODELS: tuple[str, ...] = ("mixture", "huber", "gate", "gaussian")
#: What the multipath replies are for the mixture: position information, or outliers.
MULTIPATH: tuple[str, ...] = ("signal", "outlier")
