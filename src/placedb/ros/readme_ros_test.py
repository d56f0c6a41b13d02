#!/usr/bin/python3
"""ros_readme_test: runs the README's ROS block ("On ROS", between the
ros-readme-test markers) verbatim, as a user would paste it into bash, and
checks what it promises:
- the database is the one `make demo` makes (scripts/demo.sh holds the same
  build command; this test runs it itself, so it needs no demo run);
- the answers file has, for each answer, the frame's timestamp and, for each
  match, the keyframe's pose and source image;
- `rostopic echo -n 1 /answers` decodes placedb_msgs/Answer (genpy modules);
- both feed runs into the one running voter are answered, each reporting its
  run;
- installed (`cmake --install` into a scratch prefix), the nodes, launch files
  and messages are found the same way.

The block runs in a temporary folder laid out as the checkout is (build/ and
data/ are links to this build and the data, out/demo/ holds the database), on
a free loopback port given only through ROS_MASTER_URI, with its own ROS_HOME
and ROS_LOG_DIR. It runs in a session of its own: whatever is left of it at
the end is stopped by PID (SIGTERM, SIGKILL after 20 s).

    readme_ros_test.py SOURCE_DIR BUILD_DIR PLACEDB_BINARY
"""
import json
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time

BEGIN = "<!-- ros-readme-test: begin"
END = "<!-- ros-readme-test: end -->"
# The database command, as scripts/demo.sh writes it (OUT=out/demo) and as
# this test runs it (PLACEDB: the build's placedb).
DEMO_BUILD = '"$PLACEDB" build --tum data/tum_fr3_office_32 --out "$OUT/db_tum_office" --overwrite --quiet'
FAILURES = []


def check(ok, what):
    if not ok:
        FAILURES.append(what)
        print("FAILED: " + what, flush=True)
    return ok


def readme_block(source_dir):
    text = open(os.path.join(source_dir, "README.md"), encoding="utf-8").read()
    if text.count(BEGIN) != 1 or text.count(END) != 1:
        sys.exit("README.md: expected one pair of ros-readme-test markers")
    region = text[text.index(BEGIN):text.index(END)]
    blocks = re.findall(r"^```sh\n(.*?)^```\n", region, re.S | re.M)
    if len(blocks) != 1:
        sys.exit("README.md: expected one ```sh block between the ros-readme-test markers, found %d"
                 % len(blocks))
    return blocks[0]


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def session_pids(sid):
    """The processes of session `sid` (this test's script and what it started)."""
    pids = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = open("/proc/%s/stat" % entry).read()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        # state ppid pgrp session ...
        if int(fields[3]) == sid and int(entry) != os.getpid():
            pids.append(int(entry))
    return pids


def stop_session(sid):
    pids = session_pids(sid)
    for pid in pids:
        try:
            os.kill(pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
    until = time.monotonic() + 20
    while session_pids(sid) and time.monotonic() < until:
        time.sleep(0.1)
    for pid in session_pids(sid):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def check_installed(build_dir, tmp):
    """After `cmake --install`, the prefix is a ROS package path too: rospack
    finds placedb (its launch files) and placedb_msgs, whose Python classes
    load, with the C++ classes' MD5 sums."""
    prefix = os.path.join(tmp, "prefix")
    done = subprocess.run(["cmake", "--install", build_dir, "--prefix", prefix],
                          capture_output=True, text=True)
    if not check(done.returncode == 0, "cmake --install: " + done.stdout[-2000:] + done.stderr):
        return
    env = dict(os.environ)
    env.update({"ROS_PACKAGE_PATH": os.path.join(prefix, "share") + ":/usr/share",
                "PYTHONPATH": os.path.join(prefix, "lib", "python3", "dist-packages"),
                "ROS_HOME": os.path.join(tmp, "ros_home")})
    header = open(os.path.join(build_dir, "include", "placedb_msgs", "Answer.h")).read()
    md5 = re.search(r'MD5Sum< ::placedb_msgs::Answer_<ContainerAllocator> >\s*\{.*?return "([0-9a-f]{32})"',
                    header, re.S)
    probe = ("import rospkg, roslib.message\n"
             "print(rospkg.RosPack().get_path('placedb'))\n"
             "print(roslib.message.get_message_class('placedb_msgs/Answer')._md5sum)\n")
    out = subprocess.run(["/usr/bin/python3", "-c", probe], env=env, capture_output=True, text=True)
    check(out.returncode == 0 and out.stdout.split() == [os.path.join(prefix, "share", "placedb"),
                                                         md5.group(1) if md5 else "?"],
          "installed: placedb and placedb_msgs found, Answer loads: " + out.stdout + out.stderr)
    check(os.path.exists(os.path.join(prefix, "share", "placedb", "launch", "placedb.launch")) and
          os.access(os.path.join(prefix, "lib", "placedb", "placedb_voter"), os.X_OK),
          "installed: the launch files and the nodes")


def main():
    source_dir, build_dir, placedb = sys.argv[1:4]
    script = readme_block(source_dir)
    demo = open(os.path.join(source_dir, "scripts", "demo.sh"), encoding="utf-8").read()
    check("\nOUT=out/demo\n" in demo and DEMO_BUILD in demo,
          "scripts/demo.sh builds the README's database with: " + DEMO_BUILD)
    check("out/demo/db_tum_office" in script, "the README's block runs on out/demo/db_tum_office")

    tmp = tempfile.mkdtemp(prefix="placedb_readme_ros_")
    os.symlink(os.path.abspath(build_dir), os.path.join(tmp, "build"))
    os.symlink(os.path.join(os.path.abspath(source_dir), "data"), os.path.join(tmp, "data"))
    os.makedirs(os.path.join(tmp, "out", "demo"))
    command = DEMO_BUILD.replace('"$PLACEDB"', placedb).replace('"$OUT', '"out/demo')
    built = subprocess.run(["bash", "-c", command], cwd=tmp, capture_output=True, text=True)
    if not check(built.returncode == 0, "the database builds: " + built.stdout + built.stderr):
        return 1
    with open(os.path.join(tmp, "readme_block.sh"), "w") as f:
        f.write(script)

    env = dict(os.environ)
    env.pop("ROS_HOSTNAME", None)
    env.update({
        "ROS_MASTER_URI": "http://127.0.0.1:%d" % free_port(),
        "ROS_IP": "127.0.0.1",
        "ROS_HOME": os.path.join(tmp, "ros_home"),
        "ROS_LOG_DIR": os.path.join(tmp, "ros_home", "log"),
    })
    os.makedirs(env["ROS_LOG_DIR"])
    log_path = os.path.join(tmp, "readme_block.log")
    print("running the README's block in %s, master %s" % (tmp, env["ROS_MASTER_URI"]), flush=True)
    with open(log_path, "w") as log:
        shell = subprocess.Popen(["bash", "readme_block.sh"], cwd=tmp, env=env, stdout=log,
                                 stderr=subprocess.STDOUT, start_new_session=True)
        try:
            code = shell.wait(timeout=600)  # a limit that only ends a hang
        except subprocess.TimeoutExpired:
            code = None
        stop_session(shell.pid)
        if code is None:
            shell.wait()
    output = open(log_path, errors="replace").read()
    print(output[-6000:], flush=True)
    check(code is not None, "the README's block ends (it hung for 600 s)")

    # rostopic decoded an Answer (its YAML fields, which only rostopic prints).
    check(re.search(r"^frame_seq: \d+$", output, re.M) and re.search(r"^run_id: \"?[0-9a-f]{16}", output, re.M)
          and "partitions_answered: [" in output,
          "rostopic echo -n 1 /answers prints a decoded placedb_msgs/Answer")
    check("Cannot load message class" not in output, "rostopic loads placedb_msgs/Answer")
    # Both feed runs reported, each with every frame answered or accounted for.
    reports = re.findall(r"placedb_feed: run ([0-9a-f]{16}): (\d+) frames sent, (\d+) answered "
                         r"\((\d+) complete, (\d+) partial\), (\d+) never answered", output)
    check(len(reports) == 2, "two feed reports, found %d" % len(reports))

    answers_path = os.path.join(tmp, "out", "ros_answers.jsonl")
    lines = []
    if check(os.path.exists(answers_path), "the answers file exists"):
        lines = [json.loads(l) for l in open(answers_path) if l.strip()]
    runs = {}
    for a in lines:
        runs.setdefault(a["run"], []).append(a)
        check(a["timestamp"] > 1e9, "frame %s: the frame's timestamp (%s)" % (a["frame_seq"], a["timestamp"]))
        if a["keyframe_id"] >= 0:
            check(a["source"].endswith(".png") and "tum_fr3_office_32" in a["source"],
                  "frame %s: the keyframe's source image (%r)" % (a["frame_seq"], a["source"]))
            for r in a["result"]["ranked"]:
                check(r["source"] != "" and r["timestamp"] > 1e9,
                      "frame %s: ranked keyframe %s described" % (a["frame_seq"], r["keyframe_id"]))
    with_pose = [a for a in lines if a["pose"] is not None]
    # 30 of the 32 keyframes have a ground-truth pose within 0.02 s.
    check(len(with_pose) >= 1, "answers with a pose: %d of %d" % (len(with_pose), len(lines)))
    for a in with_pose:
        check(len(a["pose"]["translation"]) == 3 and len(a["pose"]["quaternion_xyzw"]) == 4,
              "frame %s: a pose %s" % (a["frame_seq"], a["pose"]))
    for run, sent, answered, complete, partial, never in reports:
        sent, answered = int(sent), int(answered)
        check(sent == 32 and answered + int(never) == sent and int(complete) + int(partial) == answered,
              "run %s: the report adds up" % run)
        check(len(runs.get(run, [])) == answered,
              "run %s: %d answers in the file, the feed counted %d" % (run, len(runs.get(run, [])), answered))
        check(answered >= 1, "run %s: answered" % run)
    check_installed(build_dir, tmp)
    if not FAILURES:
        subprocess.run(["rm", "-rf", tmp])
        print("ros_readme_test: passed (%d answers, %d with a pose)" % (len(lines), len(with_pose)))
        return 0
    print("ros_readme_test: %d failures; the run is in %s" % (len(FAILURES), tmp))
    return 1


if __name__ == "__main__":
    sys.exit(main())
