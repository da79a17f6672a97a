"""The built-in demo: a digital performer and a stylised character made by the project's own code.

:func:`run_demo` runs the whole chain with ground truth; :mod:`facepuppet.demo.performer` renders the digital
performer, :mod:`facepuppet.demo.toy` builds the Toy, :mod:`facepuppet.demo.monkey` the Monkey,
:mod:`facepuppet.demo.script` holds the key expressions and the scripted performance.
"""

from facepuppet.demo.run import DemoConfig, DemoResult, run_demo

__all__ = ["DemoConfig", "DemoResult", "run_demo"]
