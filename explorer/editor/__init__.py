"""The system editor dock: catalogue, fields, parameters, effects, derived results."""
