# Run by scripts/guest-test inside the arm64 guest (a real kernel: SocketCAN with vcan0 up,
# pseudo-terminals, loopback networking, the PL061 GPIO chip): the HAL's tests, the Linux
# backends among them, and can-utils' view of the bus the backends use. Any failure fails the
# run.
set -e
# The GPIO tests press the machine's power button through scripts/guest-test (PL061 line 3).
BLOCKMAP_GUEST_POWER_BUTTON=1 unit_hal_tests --gtest_brief=1
# can-utils (Debian's, arm64) and our SocketCAN backend see the same bus: a frame sent with
# cansend is what candump prints.
candump -n 1 vcan0 > /tmp/candump.txt &
sleep 0.3
cansend vcan0 401#FFF9000080000102
wait
grep -q "401   \[8\]  FF F9 00 00 80 00 01 02" /tmp/candump.txt
echo "guest_hal: all passed"
