"""The papers' state-space models and data generators."""
