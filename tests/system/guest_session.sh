# Run by scripts/guest-test inside the arm64 guest: a whole mapping session on the
# real kernel's interfaces. A minute of the simulated usc_block is recorded; can-utils'
# canplayer puts the Segway's frames on vcan0 and `blockmap play` the lasers' and the GPS's
# bytes on pseudo-terminals, both at the recorded pace; the daemon (`blockmap run` with a
# [devices] table) maps from them until SIGINT. Its map must be the map `blockmap replay` makes
# of the same logs, within the particle filter's own run-to-run spread (GuestSession test).
# The daemon also holds the PL061's line 5 as its status LED (steady while every device is up)
# and follows line 3, QEMU's power button, as its mapping-enable switch (active low: released
# is on); the button is pressed near the end of the logs, and the switch's two changes must be
# in health.jsonl.
set -e
blockmap simulate --world usc_block --duration-s 60 --out /tmp/logs 2>/dev/null
cat > /tmp/robot.toml <<'CONFIG'
[devices]
base = "can:vcan0"
lasers = ["serial:/tmp/dev/laser_horizontal@500000", "serial:/tmp/dev/laser_vertical@500000"]
gps = "serial:/tmp/dev/gps@9600"
status_led = "gpio:gpiochip0:5"
enable_switch = "gpio:gpiochip0:3"
enable_switch_active_low = true
[daemon]
reconnect_first_s = 0.05
reconnect_max_s = 0.2
snapshot_every_s = 5
# The guest's ARM is emulated, several times slower than a robot's: an extraction can hold the
# pipeline for over the default queue's 0.4 s of scans, and its GPS reader, held up for up to a
# second, stamps fixes back that far, which the merge then waits for (the fixes' backdating).
# 3.4 s of scans and 5 s of the base's 100 Hz, so none is refused (one run with the machine's
# both cores busy beside the guest refused 65 of the base's with the default 2.6 s).
scan_queue_messages = 256
base_queue_messages = 512
# Both maps are drawn 12 s late, with the particle filter's smoothed path: in the loop's first
# minute its heading is still settling, and drawn live two runs of it differ by up to 20 deg.
[mapper]
pose_lag_s = 12
CONFIG
printf '[mapper]\npose_lag_s = 12\n' > /tmp/lag.toml
blockmap run --config /tmp/robot.toml --out /tmp/out 2> /tmp/run.log &
daemon=$!
sleep 1  # the daemon is up, waiting for the serial lines to appear
canplayer -I /tmp/logs/rmp.candump vcan0=can0 &
player=$!
blockmap play /tmp/logs --pty-dir /tmp/dev 2> /tmp/play.log &
playing=$!
# Mid-session, every device up: the LED is held by the daemon and lit (the kernel's own view).
sleep 20
mount -t debugfs debugfs /sys/kernel/debug
grep -E "^ *gpio-[0-9]+ +\(.*\|blockmap +\) out hi" /sys/kernel/debug/gpio ||
  { cat /sys/kernel/debug/gpio; echo "guest_session: the status LED is not lit"; exit 1; }
# The button is pressed while the logs still play (they last 60 s), and the daemon is stopped
# about 3 s before they end, while every device is still up. (Stopped once the feeds had
# ended, it could see its serial lines close first: the emulated pipeline runs behind the
# readers, and a health record due in its backlog reported the links' live state, already
# lost.)
sleep 25
echo "guest-request: power-button"
sleep 12
kill -INT $daemon
wait $daemon || { cat /tmp/run.log; exit 1; }
# Nobody reads the lines now: each of play's writes would wait 200 ms before it is dropped.
kill -INT $playing
wait $playing
wait $player
grep -E "^device|^mapped|^enable switch|^status LED|^panel" /tmp/run.log
tail -n 1 /tmp/play.log
tail -n 1 /tmp/out/health.jsonl | grep -q '"switch_changes":2,' ||
  { tail -n 1 /tmp/out/health.jsonl; echo "guest_session: the button's press and release are not in health.jsonl"; exit 1; }
blockmap replay /tmp/logs --config /tmp/lag.toml --out /tmp/replay 2>/dev/null
# The checks live beside the daemon's fault tests; a filter that matched nothing would pass.
daemon_fault_tests --gtest_list_tests --gtest_filter='GuestSession.*' | grep -q '^  ' ||
  { echo "guest_session: daemon_fault_tests has no GuestSession tests"; exit 1; }
BLOCKMAP_GUEST_SESSION=/tmp daemon_fault_tests --gtest_brief=1 --gtest_filter='GuestSession.*'
echo "guest_session: passed"
