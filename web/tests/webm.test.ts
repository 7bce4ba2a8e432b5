import { describe, expect, it } from 'vitest';
import { frameTimestampUs, overWhite } from '../src/webm';

describe('WebM timing', () => {
  it('puts frame i at exactly i / fps, whatever the solve time', () => {
    expect(frameTimestampUs(0, 24)).toBe(0);
    expect(frameTimestampUs(60, 24)).toBe(2_500_000);
    expect(frameTimestampUs(59, 30)).toBe(1_966_667);
    const gaps = Array.from({ length: 60 }, (_, i) => frameTimestampUs(i + 1, 24) - frameTimestampUs(i, 24));
    expect(new Set(gaps)).toEqual(new Set([41_666, 41_667]));
  });
});

describe('WebM pixels', () => {
  it('draws transparent pixels over white, as inkwarp render flattens an MP4', () => {
    const px = new Uint8Array([10, 20, 30, 255, 0, 0, 0, 0, 200, 0, 100, 128]);
    expect(overWhite(px)).toBe(true);
    expect([...px]).toEqual([10, 20, 30, 255, 255, 255, 255, 255, 227, 127, 177, 255]);
    expect(overWhite(new Uint8Array([1, 2, 3, 255]))).toBe(false);
    // An opaque picture's squeezed edge (alpha 252) is drawn over white, with no word.
    const edge = new Uint8Array([0, 0, 0, 252]);
    expect(overWhite(edge)).toBe(false);
    expect([...edge]).toEqual([3, 3, 3, 255]);
  });
});
