"""The online loop's outputs: the browser viewer, the VMC protocol and Live Link Face senders.

Each output is a :class:`Sender`: the live loop calls ``send(frame)`` with a :class:`LiveFrame` once per
frame (it never blocks) and ``close()`` at the end. :class:`LatencyStats` keeps the session's latency
percentiles and fps in bounded memory. The senders' packages are the ``live`` extra
(``pip install "facepuppet[live]"``), imported when a sender is made.
"""

from facepuppet.live.frame import LiveFrame, Sender, is_loopback, parse_address, warn_if_exposed
from facepuppet.live.livelink import LiveLinkConfig, LiveLinkSender
from facepuppet.live.stats import LatencyStats
from facepuppet.live.viewer import ViewerConfig, ViewerServer
from facepuppet.live.vmc import VmcConfig, VmcSender, unity_quaternion

__all__ = ["LiveFrame", "Sender", "parse_address", "is_loopback", "warn_if_exposed",
           "VmcConfig", "VmcSender", "unity_quaternion", "LiveLinkConfig", "LiveLinkSender",
           "ViewerConfig", "ViewerServer", "LatencyStats"]
