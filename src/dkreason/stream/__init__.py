"""The Stream Processor (thesis 2.3.2, 4.4): topics → merged fluents → synchronised states."""
