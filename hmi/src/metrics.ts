// The real-time figures from GET /metrics (Prometheus text), polled every ~2 s.
// Averages are over the last poll interval (difference of _sum and _count).

export interface Histogram {
  sum: number;
  count: number;
  buckets: [number, number][]; // [le seconds, cumulative count]
}

export interface Metrics {
  scalars: Map<string, number>;
  hist: Map<string, Histogram>;
}

export function parseMetrics(text: string): Metrics {
  const scalars = new Map<string, number>();
  const hist = new Map<string, Histogram>();
  const h = (name: string): Histogram => {
    let x = hist.get(name);
    if (!x) hist.set(name, (x = { sum: 0, count: 0, buckets: [] }));
    return x;
  };
  for (const line of text.split('\n')) {
    if (!line || line.startsWith('#')) continue;
    const m = /^([a-zA-Z_:][\w:]*)(\{[^}]*\})?\s+(\S+)/.exec(line);
    if (!m) continue;
    const [, name, labels, raw] = m;
    const v = Number(raw);
    if (name.endsWith('_bucket')) {
      const le = /le="([^"]+)"/.exec(labels ?? '');
      if (le) h(name.slice(0, -7)).buckets.push([le[1] === '+Inf' ? Infinity : Number(le[1]), v]);
    } else if (name.endsWith('_sum') && !labels) {
      h(name.slice(0, -4)).sum = v;
      scalars.set(name, v);
    } else if (name.endsWith('_count') && !labels) {
      h(name.slice(0, -6)).count = v;
      scalars.set(name, v);
    } else {
      scalars.set(labels ? `${name}${labels}` : name, v);
    }
  }
  return { scalars, hist };
}

/** Upper bound of the bucket holding quantile q over the window between two snapshots. */
export function quantile(now: Histogram, before: Histogram | undefined, q: number): number | null {
  const base = new Map(before?.buckets ?? []);
  const total = now.count - (before?.count ?? 0);
  if (total <= 0) return null;
  for (const [le, c] of now.buckets) {
    if (c - (base.get(le) ?? 0) >= q * total) return le;
  }
  return null;
}

export function fmtSeconds(s: number | null | undefined): string {
  if (s === null || s === undefined || !Number.isFinite(s)) return '—';
  if (s < 1e-3) return `${(s * 1e6).toFixed(s < 1e-5 ? 1 : 0)} µs`;
  if (s < 1) return `${(s * 1e3).toFixed(s < 1e-2 ? 2 : 1)} ms`;
  return `${s.toFixed(2)} s`;
}
