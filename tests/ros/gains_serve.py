"""``jointctl serve ARGS`` with the PID reconfigure servers attached, in its own process.

    python gains_serve.py ROBOT --controllers NAME ...

Until RosNode.__init__ calls attach_gain_servers itself, this wraps it to do so at its end; once it
does, the wrapper is not installed (no second server on the same names).
"""

import inspect
import sys

import jointctl.ros.node as node_module
from jointctl.cli import main
from jointctl.ros.gains import attach_gain_servers

if "attach_gain_servers" not in inspect.getsource(node_module.RosNode.__init__):
    original_init = node_module.RosNode.__init__

    def init_with_gain_servers(self, *args, **kwargs):
        original_init(self, *args, **kwargs)
        self.gain_servers = attach_gain_servers(self)

    node_module.RosNode.__init__ = init_with_gain_servers

if __name__ == "__main__":
    sys.exit(main(["serve", *sys.argv[1:]]))
