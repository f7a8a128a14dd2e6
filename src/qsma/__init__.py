"""qsma: quasi-static modal analysis of jointed structures with frictional contact,
solved on a model statically condensed to the contact interface."""

__version__ = "0.1.0"
