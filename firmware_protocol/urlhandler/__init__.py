"""pyserial URL handlers; ``protocol_sim.py`` serves ``sim://``."""
