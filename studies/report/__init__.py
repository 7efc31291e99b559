"""The HTML report of a result folder (``hingelab report``): page, sections and pictures."""
