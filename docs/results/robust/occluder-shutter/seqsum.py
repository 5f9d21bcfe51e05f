"""Summarises sequence-protocol JSON files per object and shutter: single-frame and fused failure / wrong rates, mean over backgrounds, and per background."""
import json, sys
for o in ['fruitbox', 'can', 'duck']:
    for ms in [0, 33, 100, 200]:
        try:
            r = json.load(open(f'{sys.argv[1]}/seq-{o}-{ms}.json'))
        except OSError:
            print(o, ms, 'missing'); continue
        rows = r['rows']
        m = lambda k: 100 * sum(x[k] for x in rows) / len(rows)
        print(f"{o:8} {ms:3} ms: single fail {m('single_failure_rate'):.1f} wrong {m('single_wrong_rate'):.2f}; fused fail {m('fused_failure_rate'):.1f} wrong {m('fused_wrong_rate'):.2f} |",
              ' '.join(f"{x['background']} {100*x['single_wrong_rate']:.1f}/{100*x['fused_wrong_rate']:.1f}" for x in rows))
