# Run by scripts/guest-test inside the arm64 guest (a real kernel: SocketCAN with vcan0 up,
# pseudo-terminals, loopback networking, the PL061 GPIO chip, a USB host and gadget in one
# kernel): the HAL's tests, the Linux backends among them; the daemon with a TiM on USB that is
# unplugged and plugged back; and can-utils' view of the bus the backends use. Any failure
# fails the run.
set -e
# A SICK TiM on the guest's own USB bus: tim_gadget serves a FunctionFS function of a gadget
# with SICK's ids (19a2:5001), bound to dummy_hcd's UDC; the kernel's host side enumerates it
# and the libusb tests open it as a TiM.
gadget=/sys/kernel/config/usb_gadget/tim
mkdir $gadget
echo 0x19a2 > $gadget/idVendor
echo 0x5001 > $gadget/idProduct
mkdir $gadget/strings/0x409 $gadget/configs/c.1 $gadget/functions/ffs.tim
echo "SICK AG" > $gadget/strings/0x409/manufacturer
echo "TiM5xx (blockmap test gadget)" > $gadget/strings/0x409/product
echo 18340123 > $gadget/strings/0x409/serialnumber
ln -s $gadget/functions/ffs.tim $gadget/configs/c.1/
mkdir -p /dev/ffs-tim
mount -t functionfs tim /dev/ffs-tim
data=$(find / -path '*/tests/data/cola/sick_scan_xd_test_pcapng_all16_frames.bin' 2>/dev/null | head -n 1)
tim_gadget /dev/ffs-tim "$data" > /tmp/tim_gadget.log 2>&1 &
gadget_pid=$!
stop_gadget() { kill $gadget_pid; cat /tmp/tim_gadget.log; }
sleep 0.5
echo dummy_udc.0 > $gadget/UDC || { stop_gadget; exit 1; }
# The GPIO tests press the machine's power button through scripts/guest-test (PL061 line 3).
unit_hal_tests --gtest_brief=1 || { stop_gadget; exit 1; }
BLOCKMAP_GUEST_POWER_BUTTON=1 BLOCKMAP_GUEST_TIM_UDC=$gadget/UDC linux_backend_tests --gtest_brief=1 ||
  { stop_gadget; exit 1; }
# The daemon with the modern variant's TiM (its serial number) and the RMP on vcan0: the TiM is
# unplugged for a second and plugged back while it maps; the reader finds it again, starts it
# again, and the scans go on.
cat > /tmp/tim.toml <<'CONFIG'
[robot]
spec = "rmp_tim"
[devices]
base = "can:vcan0"
lasers = ["usb:19a2:5001:18340123"]
[daemon]
reconnect_first_s = 0.1
reconnect_max_s = 0.4
CONFIG
# Each step waits for the daemon to report the one before, not for a fixed time: under an
# emulated CPU shared with other test trees the daemon's start-up alone can take seconds, and an
# unplug before the first open would test nothing.
wait_for() {  # wait_for PATTERN SECONDS: until the daemon's log has a line matching PATTERN
  tenths=0
  until grep -qE "$1" /tmp/tim_run.log; do
    tenths=$((tenths + 1))
    [ $tenths -le $(($2 * 10)) ] || { echo "guest_hal: no \"$1\" from the daemon in $2 s"; return 1; }
    sleep 0.1
  done
}
blockmap run --config /tmp/tim.toml --out /tmp/tim_out 2> /tmp/tim_run.log &
daemon=$!
fail_daemon() { kill -INT $daemon; wait $daemon; cat /tmp/tim_run.log; stop_gadget; exit 1; }
wait_for "^device laser_horizontal: up" 60 || fail_daemon
sleep 2
echo "" > $gadget/UDC
wait_for "^device laser_horizontal: lost" 30 || fail_daemon
sleep 1
echo dummy_udc.0 > $gadget/UDC
wait_for "^device laser_horizontal: up \(opened 2 times\)" 60 || fail_daemon
sleep 2
kill -INT $daemon
wait $daemon || { cat /tmp/tim_run.log; stop_gadget; exit 1; }
grep -E "^device laser" /tmp/tim_run.log
grep -q "^device laser_horizontal: lost" /tmp/tim_run.log &&
  grep -q "^device laser_horizontal: up (opened 2 times)" /tmp/tim_run.log &&
  grep -qE "^device laser_horizontal: [1-9][0-9]+ messages, 0 refused" /tmp/tim_run.log ||
  { cat /tmp/tim_run.log; stop_gadget; echo "guest_hal: the daemon lost the TiM"; exit 1; }
stop_gadget
# can-utils (Debian's, arm64) and our SocketCAN backend see the same bus: a frame sent with
# cansend is what candump prints.
candump -n 1 vcan0 > /tmp/candump.txt &
candump_pid=$!
sleep 0.3
cansend vcan0 401#FFF9000080000102
wait $candump_pid
grep -q "401   \[8\]  FF F9 00 00 80 00 01 02" /tmp/candump.txt
echo "guest_hal: all passed"
