"""The built-in demo: a digital performer and a stylised character made by the project's own code."""
