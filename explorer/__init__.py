"""The Phase Explorer application: Qt GUI, integrator worker thread, CLI and exports."""

from explorer.qt_compat import protect_singletons

protect_singletons()
