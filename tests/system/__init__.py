"""System tests: processes, clusters, browsers, emulators, simulated databases."""
