"""Human perception of tilt and rotation: the Merfeld–Zupan and Laurens–Angelaki models, their
parameters, the classic paradigms and ``perceive`` that runs a model on a motion."""
