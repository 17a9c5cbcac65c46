"""The ground every other part stands on: rotations (``so3``), integration steps, constants,
errors, work sizing and figure helpers. Nothing here knows a model or an experiment."""
