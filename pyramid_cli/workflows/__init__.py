"""The planners of whole workflows: pyramids, MIP chains, fill and blend as single plans, and the cost limits
checked before any work starts."""
