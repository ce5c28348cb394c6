"""cmp.py BASE file.json ... : mean AEE per regime and method, change against method BASE; '!' = worse than
max(0.001 px, 0.5 %) (the helper rules' tolerance)."""
import json
import sys

base, files = sys.argv[1], sys.argv[2:]
rows, meths = {}, []
for f in files:
    d = json.load(open(f))
    for reg, r in d['regimes'].items():
        for k, v in r['methods'].items():
            if k not in meths:
                meths.append(k)
            rows.setdefault(reg, {})[k] = v['aee']
print('| regime | ' + ' | '.join(meths) + ' |')
print('|---|' + '---:|' * len(meths))
for reg, m in rows.items():
    b = m.get(base)
    cells = []
    for k in meths:
        if k not in m:
            cells.append('')
            continue
        a = m[k]
        if k == base or b is None:
            cells.append(f'{a:.4f}')
        else:
            bad = a - b > max(0.001, 0.005 * b)
            cells.append(f"{a:.4f} ({100 * (a - b) / b:+.1f} %{'!' if bad else ''})")
    print(f'| {reg} | ' + ' | '.join(cells) + ' |')
