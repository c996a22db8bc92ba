"""dynamic_reconfigure's Python client in its own process (rospy allows one node per process).

    python reconfigure_client.py SERVER JSON_CHANGES    update, print the server's answer
    python reconfigure_client.py SERVER                 print the current configuration

Prints one JSON line: the parameters (groups left out) and, under "_descriptions", each
parameter's type, min and max as the server advertises them.
"""

import json
import math
import sys

import rospy
from dynamic_reconfigure.client import Client


def plain(value):
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)  # "inf", "-inf", "nan": JSON has no such numbers
    return value


def main() -> None:
    server = sys.argv[1]
    rospy.init_node("reconfigure_client", anonymous=True, disable_signals=True)
    client = Client(server, timeout=20)
    if len(sys.argv) > 2:
        changes = json.loads(sys.argv[2], parse_constant=float)
        config = client.update_configuration(changes)
    else:
        config = client.get_configuration(timeout=20)
    out = {k: plain(v) for k, v in config.items() if k != "groups"}
    out["_descriptions"] = {d["name"]: {"type": d["type"], "min": plain(d["min"]), "max": plain(d["max"])}
                            for d in client.get_parameter_descriptions(timeout=20)}
    print(json.dumps(out))
    client.close()
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
