#!/bin/bash
# docs/CI.md's GitLab job (its before_script, script and after_script lines, in order) in a fresh Debian 12 root
# made by debootstrap under build/debian12-ci (as root; debootstrap from Debian's archive): no venv, no pip cache,
# no bench, an empty HOME, the environment cleared (env -i), the repository's HEAD as a git URL, the example
# project as the job's tests/hil, its law as my_law. `bash scripts/gitlab_job_debian12.sh [--fresh]`; --fresh
# makes the root again (else its Debian packages stay from the last run: the apt step then costs seconds).
set -u
TOP=$(cd "$(dirname "$0")/.." && pwd)
R=$TOP/build/debian12-ci
J=/job
if [ "${1:-}" = --fresh ] || [ ! -x $R/usr/bin/python3 ]; then
    rm -rf $R
    command -v debootstrap >/dev/null || apt-get install -y -q debootstrap
    debootstrap --variant=minbase --include=ca-certificates,python3,python3-venv,python3-pip,git bookworm $R \
        http://deb.debian.org/debian >/dev/null || { echo "debootstrap failed"; exit 1; }
fi
rm -rf $R/src $R$J $R/root/.cache $R/venv
mkdir -p $R/src $R$J/tests
git clone -q --bare $TOP $R/src/pmsm-hil-bench.git
cp -r $TOP/examples/ci_project $R$J/tests/hil
cp -r $TOP/examples/laws $R$J/tests/laws
cp -r $TOP/examples/laws/complex_vector_pi $R$J/my_law
for m in proc sys dev dev/pts dev/shm; do mountpoint -q $R/$m || mount --bind /$m $R/$m; done
cp /etc/resolv.conf $R/etc/resolv.conf
# this machine's network: its egress proxy's CA (a runner on this network would carry the same), nothing else
cp /usr/local/share/ca-certificates/*.crt $R/usr/local/share/ca-certificates/ 2>/dev/null
chroot $R update-ca-certificates >/dev/null 2>&1
step() { echo "=== $(date +%T) $*"; S=$(date +%s); chroot $R /usr/bin/env -i HOME=/root PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin CI=true bash -c "cd $J && $*" </dev/null; rc=$?; echo "=== rc=$rc $(( $(date +%s)-S )) s"; return $rc; }
ok=0
step 'apt-get update -q && DEBIAN_FRONTEND=noninteractive apt-get install -y -q build-essential qemu-system-x86 linux-image-amd64 busybox-static can-utils file iproute2 procps >/tmp/apt.log 2>&1 || { tail -20 /tmp/apt.log; exit 1; }' || ok=1
[ $ok = 0 ] && { step 'python3 -m venv /venv && /venv/bin/pip install -q --cert /etc/ssl/certs/ca-certificates.crt --upgrade pip && /venv/bin/pip --version' || ok=1; }
[ $ok = 0 ] && { step 'export PIP_CERT=/etc/ssl/certs/ca-certificates.crt; /venv/bin/pip install -q "pmsm-hil-bench @ git+file:///src/pmsm-hil-bench.git" && du -sh /venv' || ok=1; }
[ $ok = 0 ] && { step '/venv/bin/bench box up' || ok=1; }
[ $ok = 0 ] && { step '/venv/bin/pytest tests/hil --hil-bus vcan0 --hil-law=my_law --hil-out=hil-runs --junitxml=hil.xml -o junit_logging=system-out -q -rA 2>&1 | grep -v "^  cc" | tail -25; exit ${PIPESTATUS[0]}' || ok=1; }
step '/venv/bin/bench box down'
step 'ls hil-runs; grep -c "<testcase" hil.xml; grep -o "name=\"hil_[a-z_]*\"" hil.xml | sort | uniq -c | head -20'
for m in dev/shm dev/pts dev sys proc; do umount $R/$m 2>/dev/null; done
echo "job rc=$ok"
exit $ok
