#!/bin/busybox sh
# init of the vcan test guest (tests/vcan_vm): load the modules listed in
# /modules.order, mount the host root over 9p, create vcan0 and vcan1, run the
# job script named on the kernel command line (vcanvm.job=DIR) chrooted into
# the host root, power off. Lines starting "vcan-vm:" on the console are the
# progress markers the host runner watches; the job's output and exit status
# travel back as files in DIR on the shared filesystem.
/bin/busybox mkdir -p /proc /sys /dev /mnt /sbin /usr/bin /usr/sbin
/bin/busybox --install -s
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev

say() { echo "vcan-vm: $*"; }
fail() { say "error: $*"; sync; poweroff -f; sleep 60; }

say "stage init"
while read -r name file; do
    out=$(insmod "$file" 2>&1) || fail "module $name failed to load: $out"
done < /modules.order
say "stage modules"

job=""
for arg in $(cat /proc/cmdline); do
    case "$arg" in vcanvm.job=*) job="${arg#vcanvm.job=}" ;; esac
done
[ -n "$job" ] || fail "no vcanvm.job= on the kernel command line"

ip link set lo up
for iface in vcan0 vcan1; do
    out=$(ip link add dev "$iface" type vcan 2>&1 && ip link set up "$iface" 2>&1) \
        || fail "could not create $iface: $out"
done
say "stage interfaces"

out=$(mount -t 9p -o trans=virtio,version=9p2000.L,msize=512000,cache=loose hostroot /mnt 2>&1) \
    || fail "could not mount the host root over 9p: $out"
[ -f "/mnt$job/job.sh" ] || fail "job script $job/job.sh not visible in the guest"
mount --move /proc /mnt/proc && mount --move /sys /mnt/sys && mount --move /dev /mnt/dev \
    || fail "could not move proc/sys/dev into the host root"
mkdir -p /mnt/dev/shm /mnt/dev/pts
mount -t tmpfs -o mode=1777 tmpfs /mnt/dev/shm
mount -t devpts devpts /mnt/dev/pts
say "stage hostroot"

chroot /mnt /bin/sh "$job/job.sh"
say "stage job-end $?"
sync
poweroff -f
sleep 60
