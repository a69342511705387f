"""prismstation: photogrammetric orientation of ALOS-PRISM 1B2 triplets."""
__version__ = "0.1.0"
