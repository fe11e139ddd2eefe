"""Protocol declarations (YAML) shipped with hybridteam."""
