# A robust run's --errors CSV with every estimate found under recognition's
# threshold (score_margin below 1) rejected, as the rule
# acch_confidence::MIN_ACCEPTED_DETECTION_MARGIN does: computes, from a run
# of the build without the rule, what the rule alone changes (acceptance of
# those rows only; every image is rated on its own). Checked against a run
# of the build with the rule in compare.txt. Usage, from the repository
# root:
#   python3 docs/results/robust/found-faint/under_threshold_rejected.py IN.csv[.gz] OUT.csv
import csv, gzip, sys
src = (gzip.open if sys.argv[1].endswith('gz') else open)(sys.argv[1], 'rt')
rows = csv.DictReader(src)
with open(sys.argv[2], 'w', newline='') as f:
    out = csv.DictWriter(f, fieldnames=rows.fieldnames, lineterminator='\n')
    out.writeheader()
    changed = 0
    for r in rows:
        if r['score_margin'] and float(r['score_margin']) < 1 and r['accepted'] == '1':
            r['accepted'] = '0'
            changed += 1
        out.writerow(r)
print(f'{changed} accepted estimates found under the threshold rejected', file=sys.stderr)
