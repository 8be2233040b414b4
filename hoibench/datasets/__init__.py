"""Raw dataset loaders (BEHAVE, OMOMO, RICH), the synthetic HOI generator and test motion."""
