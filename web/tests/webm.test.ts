import { describe, expect, it } from 'vitest';
import { frameTimestampUs } from '../src/webm';

describe('WebM timing', () => {
  it('puts frame i at exactly i / fps, whatever the solve time', () => {
    expect(frameTimestampUs(0, 24)).toBe(0);
    expect(frameTimestampUs(60, 24)).toBe(2_500_000);
    expect(frameTimestampUs(59, 30)).toBe(1_966_667);
    const gaps = Array.from({ length: 60 }, (_, i) => frameTimestampUs(i + 1, 24) - frameTimestampUs(i, 24));
    expect(new Set(gaps)).toEqual(new Set([41_666, 41_667]));
  });
});
