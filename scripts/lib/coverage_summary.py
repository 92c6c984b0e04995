"""Line and function coverage of moslam's own code (src/ and apps/, tests left out) from the
.gcda files a coverage build's test run wrote: runs gcov in JSON mode on each, then prints the
totals, the files with most lines never run, and every function never run; with FILEs (paths
as listed), the lines of each never run, with their text.
Usage: python3 coverage_summary.py BUILD_DIR REPO_DIR [FILE ...]"""
import collections
import glob
import gzip
import json
import os
import subprocess
import sys
import tempfile


def own(path, repo):
    if not path.startswith(repo + '/'):
        return None
    rel = path[len(repo) + 1:]
    if not (rel.startswith('src/') or rel.startswith('apps/')):
        return None
    if '_test' in rel or 'testing' in rel:
        return None
    return rel


def main(build, repo, listed):
    build, repo = os.path.realpath(build), os.path.realpath(repo)
    gcdas = glob.glob(os.path.join(build, '**', '*.gcda'), recursive=True)
    if not gcdas:
        sys.exit('no .gcda files under %s: run the tests of a coverage build first' % build)
    lines = collections.defaultdict(dict)
    functions = {}
    with tempfile.TemporaryDirectory() as work:
        # One folder per .gcda: gcov names its report after the source, and a source built into
        # two targets (a command and its test) would overwrite the other's.
        for i, gcda in enumerate(gcdas):
            out = os.path.join(work, str(i))
            os.mkdir(out)
            subprocess.run(['gcov', '-j', '-o', os.path.dirname(gcda), gcda], cwd=out,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        for report in glob.glob(os.path.join(work, '*', '*.gcov.json.gz')):
            with gzip.open(report) as f:
                data = json.load(f)
            for entry in data['files']:
                rel = own(os.path.realpath(os.path.join(data.get('current_working_directory', ''),
                                                        entry['file'])), repo)
                if rel is None:
                    continue
                for fn in entry.get('functions', []):
                    key = (rel, fn['start_line'], fn['demangled_name'])
                    functions[key] = functions.get(key, 0) + fn['execution_count']
                for line in entry.get('lines', []):
                    n = line['line_number']
                    lines[rel][n] = lines[rel].get(n, 0) + line['count']
    total = sum(len(v) for v in lines.values())
    run = sum(sum(1 for c in v.values() if c > 0) for v in lines.values())
    never = sorted(k for k, v in functions.items() if v == 0)
    print('lines run by the tests: %d of %d (%.1f %%) in %d files' %
          (run, total, 100.0 * run / max(total, 1), len(lines)))
    print('functions run: %d of %d' % (len(functions) - len(never), len(functions)))
    print('\nfiles with the most lines never run:')
    worst = sorted(((sum(1 for c in v.values() if c == 0), p, len(v)) for p, v in lines.items()),
                   reverse=True)
    for missed, path, n in worst[:15]:
        print('  %5d of %5d  %s' % (missed, n, path))
    print('\nfunctions never run:')
    for path, line, name in never:
        print('  %s:%d %s' % (path, line, name[:110]))
    for path in listed:
        if path not in lines:
            sys.exit('%s: no coverage data (not built into the coverage build, or not ours)' % path)
        with open(os.path.join(repo, path)) as f:
            text = f.read().splitlines()
        print('\nlines of %s never run:' % path)
        for n in sorted(k for k, c in lines[path].items() if c == 0):
            print('  %5d  %s' % (n, text[n - 1].strip() if n <= len(text) else '?'))


if __name__ == '__main__':
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], sys.argv[3:])
