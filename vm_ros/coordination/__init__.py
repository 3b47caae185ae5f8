"""Muscle coordination from motion: drives that reproduce target joint moments."""
