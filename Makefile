# jointctl: two commands.
#   make demo   create .venv, install, run the chapter's experiments into out/demo/
#   make test   create .venv, install with test extras, run the test suite
#   make bench  run the speed and memory benchmarks, printing ratios to a bare MuJoCo loop
#   make ros    install Debian's ROS 1 packages and generate jointctl's message classes (make test does it)
#   make ros2   install ROS 2 (Jazzy, with ros2_control) unless one is found (make test does it)
#   make web    build the tuning page's libraries (uPlot, three.js; npm registry) into the package
#   make browser  install Debian's Chromium and ChromeDriver for the page's browser tests (make test does it)
#   make render   install Mesa's software EGL and ffmpeg for videos of runs (make demo and make test do it)
#
# The virtual environment is made from Debian's /usr/bin/python3 with access to its
# system packages, so the ROS 1 packages Debian ships (rospy, actionlib) import beside
# the pinned pip dependencies. Set PYTHON to use another interpreter.

PYTHON ?= $(shell test -x /usr/bin/python3 && echo /usr/bin/python3 || command -v python3)
VENV   ?= .venv
PY     := $(VENV)/bin/python
OUT    ?= out/demo

WEB_ASSET := src/jointctl/tuning/static/vendor/three.module.js

.PHONY: demo test bench venv ros ros2 web browser render clean

$(VENV)/.installed: pyproject.toml scripts/bootstrap.sh
	PYTHON=$(PYTHON) VENV=$(VENV) bash scripts/bootstrap.sh
	touch $@

$(WEB_ASSET): web/package-lock.json scripts/build_web.sh
	bash scripts/build_web.sh

web: $(WEB_ASSET)

venv: $(VENV)/.installed web

demo: venv render
	$(VENV)/bin/jointctl demo --out $(OUT)

# ROS 1 from Debian (apt), the message classes jointctl carries (generated without catkin), and a
# .pth file so the venv imports them. See scripts/install_ros.sh and scripts/gen_ros_msgs.sh.
ros: venv
	bash scripts/install_ros.sh
	bash scripts/gen_ros_msgs.sh
	echo "$(CURDIR)/build/ros/py" > "$$($(PY) -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/jointctl_ros_msgs.pth"

# ROS 2: the user's own (JOINTCTL_ROS2_SETUP or /opt/ros/<distro>), else the prebuilt Jazzy beside the
# project. jointctl reaches it through the environment its setup.bash makes (see README, "ROS 2").
ros2:
	bash scripts/install_ros2.sh

browser:
	bash scripts/install_browser.sh

render:
	bash scripts/install_render.sh

# Tests run on $(JOBS) workers: the wall-clock ones (ROS, sockets, browser) together on one, the
# simulated-time ones spread over the others at a lower priority (tests/conftest.py); then, alone, the
# real-time measurements that need the whole machine (marked exclusive). The slowest are listed.
JOBS ?= $(shell nproc)

test: ros ros2 browser render
	$(PY) -m pytest -q -n $(JOBS) --dist loadgroup --durations=30 -m "not exclusive"
	$(PY) -m pytest -q --durations=5 -m exclusive

bench: venv render
	$(PY) benchmarks/run.py

clean:
	rm -rf $(VENV) out build web/node_modules src/jointctl/tuning/static/vendor
