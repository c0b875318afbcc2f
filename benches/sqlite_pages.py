"""SQLite pages read and written per request by accelcal.

Starts BINARY (`accelcal`) on a new SQLite database, stores 40 calibrations
for each of 64 sensors (the paper's Table 1), then counts the server's
`pread64` and `pwrite64` calls with strace (one call is one 4 KiB page, of
the database or its WAL) over 640 submissions sent one at a time, 640
history reads of 20 rows and 640 latest-coefficients reads. Counts, not
timings: they do not depend on how busy the machine is.

    cargo build --release && python3 benches/sqlite_pages.py target/release/accelcal

Needs python3 and strace (Debian: `apt-get install strace`)."""
import json, os, signal, subprocess, sys, tempfile, time, urllib.request
binary = sys.argv[1]
d = tempfile.mkdtemp(prefix='accelcal-pages-')
here = os.path.dirname(os.path.abspath(__file__))
import secrets
tok = secrets.token_urlsafe(32)
env = dict(os.environ, ACCELCAL_ADMIN_TOKEN=tok)
srv = subprocess.Popen([binary, 'serve', '--database', d + '/p.db', '--listen', '127.0.0.1:18090'], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
body = json.load(open(os.path.join(here, '..', 'examples', 'paper-table1.json')))
def call(method, path, data=None):
    req = urllib.request.Request('http://127.0.0.1:18090' + path, method=method, data=data,
        headers={'Authorization': 'Bearer ' + tok, 'Content-Type': 'application/json'})
    with urllib.request.urlopen(req) as r: return r.status, r.read()
for _ in range(100):
    try: call('GET', '/health'); break
    except Exception: time.sleep(0.1)
n = [0]
def submit(s):
    n[0] += 1
    b = dict(body, sensor_id='S%d' % s, performed_at='2024-01-01T%02d:%02d:%02dZ' % (n[0] // 3600 % 24, n[0] // 60 % 60, n[0] % 60))
    st, _ = call('POST', '/v1/calibrations', json.dumps(b).encode()); assert st == 201
for k in range(40):
    for s in range(64): submit(s)
def count(what, f, N=640):
    tr = subprocess.Popen(['strace', '-f', '-c', '-e', 'trace=pread64,pwrite64', '-p', str(srv.pid)], stderr=subprocess.PIPE, text=True)
    time.sleep(1)
    for i in range(N): f(i % 64)
    time.sleep(0.5)
    tr.send_signal(signal.SIGINT); out = tr.communicate()[1]
    calls = {l.split()[-1]: int(l.split()[3]) for l in out.splitlines() if l.strip().endswith(('pread64', 'pwrite64'))}
    print('%s: %s per request' % (what, ', '.join('%s %.1f' % (k, v / N) for k, v in sorted(calls.items()))))
count('submit (one at a time)', submit)
count('history, 20 rows', lambda s: call('GET', '/v1/sensors/S%d/calibrations?limit=20' % s))
count('coefficients', lambda s: call('GET', '/v1/sensors/S%d/coefficients' % s))
srv.send_signal(signal.SIGTERM); srv.wait()
