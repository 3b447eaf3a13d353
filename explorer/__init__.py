"""The Phase Explorer application: Qt GUI, integrator worker thread, CLI and exports."""
