"""Parse stage: user files (OWL, SSL_T text and XML, COWL, TOML, formulas) → frozen model."""
