"""Physics: flows (stream functions), the body and its coefficient laws, the equations of motion,
integrators and the registry of scenarios. The lowest layer: it imports no other layer."""
