"""The core layer: what every other layer builds on, importing none of them."""
