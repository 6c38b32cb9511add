"""Training of coastforge's own learned models on its synthetic renders (torch is a training-time extra)."""
