"""OWL reasoning over a parsed ontology (`reasoning = "owl-rl"`): entailed memberships and
sameAs, before the ontology becomes facts."""
