"""Mode libraries shipped with hybridteam (reached as ``hybridteam.modes.<lib>``)."""
