//! Every lane operation, bit for bit against the scalar Rust operation it is named after, on
//! every backend this processor runs. The inputs mix random bit patterns with NaNs (quiet,
//! signalling, with payloads, both signs), ±∞, ±0, subnormals, the conversions' edges
//! (2³¹, 2³², half-way values) and equal or opposite operands. The lane results are computed
//! inside [`dispatch`] (with the backend's target features, as the engine runs them); the
//! scalar references outside it, in code compiled for the baseline target, as the scalar
//! engine is.

use super::*;
use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg32;

/// Values per operation (a multiple of 16).
const N: usize = 16 * 2048;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Op {
    // f32 → f32
    Neg,
    Abs,
    Sqrt,
    Floor,
    Ceil,
    Trunc,
    Round,
    // (f32, f32) → f32
    Add,
    Sub,
    Mul,
    Div,
    Min,
    Max,
    MinLt,
    MaxGt,
    Copysign,
    // (f32, f32, f32) → f32
    Clamp,
    // → mask
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
    IsNan,
    IsFinite,
    Select,
    // conversions
    ToBits,
    FromBits,
    ToI32,
    ToU32,
    FromI32,
    FromU32,
    // u32
    UAdd,
    USub,
    UMul,
    UAnd,
    UOr,
    UXor,
    UShl,
    UShr,
    UShlv,
    UShrv,
    URotr,
    UMin,
    UMax,
    UEq,
    ULt,
    UGt,
    USelect,
    // u64
    QAdd,
    QSub,
    QMul,
    QAnd,
    QOr,
    QXor,
    QShl,
    QShr,
    QEq,
    QSelect,
    QFromU32,
    QLow32,
    QHigh32,
    // masks
    MAnd,
    MOr,
    MXor,
    MNot,
    MAndNot,
    MAny,
    MAll,
    MCount,
    MBits,
    Index,
    // memory and lane access
    Splat,
    SplatU,
    SplatQ,
    SetLane,
    Gather,
    GatherU,
    Compress,
    Expand,
    CompressU,
    ExpandU,
    // V3 against glam::Vec3
    VDot,
    VCross,
    VLength,
    VNormalize,
    VNormalizeOrZero,
    VMin,
    VMax,
    VMaxElement,
    VMinElement,
    VAbs,
    VAdd,
    VSub,
    VMul,
    VDiv,
    VScale,
    VDivScalar,
    VNeg,
    VEq,
    VIsFinite,
    VSelect,
}

const OPS: &[Op] = &[
    Op::Neg,
    Op::Abs,
    Op::Sqrt,
    Op::Floor,
    Op::Ceil,
    Op::Trunc,
    Op::Round,
    Op::Add,
    Op::Sub,
    Op::Mul,
    Op::Div,
    Op::Min,
    Op::Max,
    Op::MinLt,
    Op::MaxGt,
    Op::Copysign,
    Op::Clamp,
    Op::Eq,
    Op::Ne,
    Op::Lt,
    Op::Le,
    Op::Gt,
    Op::Ge,
    Op::IsNan,
    Op::IsFinite,
    Op::Select,
    Op::ToBits,
    Op::FromBits,
    Op::ToI32,
    Op::ToU32,
    Op::FromI32,
    Op::FromU32,
    Op::UAdd,
    Op::USub,
    Op::UMul,
    Op::UAnd,
    Op::UOr,
    Op::UXor,
    Op::UShl,
    Op::UShr,
    Op::UShlv,
    Op::UShrv,
    Op::URotr,
    Op::UMin,
    Op::UMax,
    Op::UEq,
    Op::ULt,
    Op::UGt,
    Op::USelect,
    Op::QAdd,
    Op::QSub,
    Op::QMul,
    Op::QAnd,
    Op::QOr,
    Op::QXor,
    Op::QShl,
    Op::QShr,
    Op::QEq,
    Op::QSelect,
    Op::QFromU32,
    Op::QLow32,
    Op::QHigh32,
    Op::MAnd,
    Op::MOr,
    Op::MXor,
    Op::MNot,
    Op::MAndNot,
    Op::MAny,
    Op::MAll,
    Op::MCount,
    Op::MBits,
    Op::Index,
    Op::Splat,
    Op::SplatU,
    Op::SplatQ,
    Op::SetLane,
    Op::Gather,
    Op::GatherU,
    Op::Compress,
    Op::Expand,
    Op::CompressU,
    Op::ExpandU,
    Op::VDot,
    Op::VCross,
    Op::VLength,
    Op::VNormalize,
    Op::VNormalizeOrZero,
    Op::VMin,
    Op::VMax,
    Op::VMaxElement,
    Op::VMinElement,
    Op::VAbs,
    Op::VAdd,
    Op::VSub,
    Op::VMul,
    Op::VDiv,
    Op::VScale,
    Op::VDivScalar,
    Op::VNeg,
    Op::VEq,
    Op::VIsFinite,
    Op::VSelect,
];

/// f32 values where the operations' special cases live.
const SPECIAL_F32: &[u32] = &[
    0x0000_0000, // +0
    0x8000_0000, // −0
    0x7f80_0000, // +∞
    0xff80_0000, // −∞
    0x7fc0_0000, // quiet NaN
    0xffc0_0000,
    0x7fc1_2345, // NaN with a payload
    0x7f80_0001, // signalling NaN
    0xff80_4321,
    0x0000_0001, // smallest subnormal
    0x807f_ffff, // largest subnormal, negative
    0x0080_0000, // smallest normal
    0x7f7f_ffff, // f32::MAX
    0xff7f_ffff,
    0x3f80_0000, // 1
    0xbf80_0000,
    0x3f00_0000, // 0.5
    0xbf00_0000,
    0x3eff_ffff, // 0.49999997
    0x3fc0_0000, // 1.5
    0x4020_0000, // 2.5
    0xc020_0000,
    0x4b00_0000, // 2²³
    0x4aff_ffff, // 2²³ − 0.5
    0x4b7f_ffff, // 2²⁴ − 1
    0x4eff_ffff, // largest below 2³¹
    0x4f00_0000, // 2³¹
    0x4f00_0001,
    0xcf00_0000, // −2³¹
    0xcf00_0001,
    0x4f7f_ffff, // largest below 2³²
    0x4f80_0000, // 2³²
    0xbf7f_ffff, // −0.99999994
    0xbf80_0001, // just below −1
];

const SPECIAL_U32: &[u32] = &[
    0,
    1,
    2,
    15,
    16,
    31,
    32,
    33,
    63,
    64,
    0xffff,
    0x1_0000,
    0xff_ffff,
    0x100_0000,
    0x100_0001,
    0x7fff_ffff,
    0x8000_0000,
    0x8000_0001,
    0xffff_ffff,
];

fn gen_f32(rng: &mut Pcg32) -> u32 {
    match rng.random_range(0..9) {
        0 => rng.random::<u32>(),
        1 => SPECIAL_F32[rng.random_range(0..SPECIAL_F32.len())],
        2 => (rng.random_range(-64i32..=64) as f32 * 0.5).to_bits(),
        3 => ((rng.random::<f32>() - 0.5) * 2000.0).to_bits(),
        // subnormals and zeros of either sign
        4 => rng.random::<u32>() & 0x807f_ffff,
        // a few ulps around a special value (the conversion and rounding edges)
        5 => {
            let s = SPECIAL_F32[rng.random_range(0..SPECIAL_F32.len())];
            s.wrapping_add(rng.random_range(0..5)).wrapping_sub(2)
        }
        // NaNs with random payloads and signs
        6 => 0x7f80_0000 | (rng.random::<u32>() & 0x807f_ffff) | 1,
        7 => (rng.random::<f32>() * 4.0).to_bits(),
        _ => (rng.random::<f32>() * 1e10).to_bits() ^ (rng.random::<u32>() & 0x8000_0000),
    }
}

fn gen_u32(rng: &mut Pcg32) -> u32 {
    match rng.random_range(0..4) {
        0 => rng.random::<u32>(),
        1 => SPECIAL_U32[rng.random_range(0..SPECIAL_U32.len())],
        2 => rng.random_range(0..70),
        _ => rng.random::<u32>() >> rng.random_range(0..32),
    }
}

fn gen_u64(rng: &mut Pcg32) -> u64 {
    match rng.random_range(0..4) {
        0 => rng.random::<u64>(),
        1 => u64::MAX >> rng.random_range(0..64),
        2 => gen_u32(rng) as u64 | (gen_u32(rng) as u64) << 32,
        _ => rng.random_range(0..70),
    }
}

/// Random masks, with whole blocks of 16 all set or all clear now and then (any, all).
fn gen_masks(rng: &mut Pcg32) -> Vec<bool> {
    let mut m = Vec::with_capacity(N);
    for _ in 0..N / 16 {
        let kind = rng.random_range(0..6);
        for _ in 0..16 {
            m.push(match kind {
                0 => true,
                1 => false,
                2 => rng.random_range(0..16) != 0,
                _ => rng.random::<bool>(),
            });
        }
    }
    m
}

const TABLE_LEN: usize = 1000;

struct Inputs {
    /// Six operands (bits: f32 and u32 in the low half), as the op reads them.
    v: [Vec<u64>; 6],
    m: Vec<bool>,
    m2: Vec<bool>,
    table_f: Vec<f32>,
    table_u: Vec<u32>,
}

/// What an operation's operands are.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    F32,
    U32,
    U64,
    /// Gather: operand 0 any u32, operand 1 an index into the tables.
    Index,
}

fn kind(op: Op) -> Kind {
    use Op::*;
    match op {
        QAdd | QSub | QMul | QAnd | QOr | QXor | QShl | QShr | QEq | QSelect | QLow32 | QHigh32
        | SplatQ | SetLane => Kind::U64,
        FromBits | FromI32 | FromU32 | UAdd | USub | UMul | UAnd | UOr | UXor | UShl | UShr
        | UShlv | UShrv | URotr | UMin | UMax | UEq | ULt | UGt | USelect | QFromU32 | SplatU
        | CompressU | ExpandU | Index => Kind::U32,
        Gather | GatherU => Kind::Index,
        _ => Kind::F32,
    }
}

fn inputs(op: Op, seed: u64) -> Inputs {
    let mut rng = Pcg32::seed_from_u64(seed);
    let k = kind(op);
    let mut v: [Vec<u64>; 6] = Default::default();
    for vj in v.iter_mut() {
        *vj = (0..N)
            .map(|_| match k {
                Kind::F32 => gen_f32(&mut rng) as u64,
                Kind::U32 => gen_u32(&mut rng) as u64,
                Kind::U64 => gen_u64(&mut rng),
                Kind::Index => gen_u32(&mut rng) as u64,
            })
            .collect();
    }
    if k != Kind::Index {
        // The second operand (of V3s: each component of the second vector) equal to the
        // first now and then, and for f32 its negation (±0 pairs, x − x, min(x, −x)).
        #[allow(clippy::needless_range_loop)] // (two operands of lane i)
        for i in 0..N {
            for (a, b) in [(0, 1), (0, 3), (1, 4), (2, 5)] {
                v[b][i] = match rng.random_range(0..8) {
                    0 => v[a][i],
                    1 if k == Kind::F32 => v[a][i] ^ 0x8000_0000,
                    _ => v[b][i],
                };
            }
        }
    }
    let m = gen_masks(&mut rng);
    let m2 = gen_masks(&mut rng);
    if k == Kind::Index {
        // Active lanes index the tables; inactive ones hold anything (never read).
        for i in 0..N {
            if m[i] {
                v[1][i] %= TABLE_LEN as u64;
            }
        }
    }
    let table_f = (0..TABLE_LEN)
        .map(|_| f32::from_bits(gen_f32(&mut rng)))
        .collect();
    let table_u = (0..TABLE_LEN).map(|_| gen_u32(&mut rng)).collect();
    Inputs {
        v,
        m,
        m2,
        table_f,
        table_u,
    }
}

/// The shift of the block of 16 that lane `i` belongs to (one shift amount per call).
fn block_shift(i: usize, bits: u32) -> u32 {
    (i / 16) as u32 % bits
}

/// The lane `set_lane` writes in the chunk starting at `c`, for width `w`.
fn set_lane_index(c: usize, w: usize) -> usize {
    (c / 16 * 7 + 3) % w
}

type Out = Vec<[u64; 3]>;

/// The scalar references, lane by lane (chunked ops by chunks of `w` lanes).
fn reference(op: Op, inp: &Inputs, w: usize) -> Out {
    let f = |k: usize, i: usize| f32::from_bits(inp.v[k][i] as u32);
    let u = |k: usize, i: usize| inp.v[k][i] as u32;
    let q = |k: usize, i: usize| inp.v[k][i];
    let fb = |x: f32| [x.to_bits() as u64, 0, 0];
    let ub = |x: u32| [x as u64, 0, 0];
    let bb = |x: bool| [x as u64, 0, 0];
    let vb = |x: Vec3| {
        [
            x.x.to_bits() as u64,
            x.y.to_bits() as u64,
            x.z.to_bits() as u64,
        ]
    };
    let va = |i: usize| Vec3::new(f(0, i), f(1, i), f(2, i));
    let vbv = |i: usize| Vec3::new(f(3, i), f(4, i), f(5, i));
    let mut out = vec![[0u64; 3]; N];
    for c in (0..N).step_by(w) {
        let chunk = c..c + w;
        match op {
            Op::MAny => out[c] = bb(inp.m[chunk].iter().any(|&b| b)),
            Op::MAll => out[c] = bb(inp.m[chunk].iter().all(|&b| b)),
            Op::MCount => out[c] = ub(inp.m[chunk].iter().filter(|&&b| b).count() as u32),
            Op::MBits => {
                out[c] = ub(inp.m[chunk]
                    .iter()
                    .enumerate()
                    .map(|(i, &b)| (b as u32) << i)
                    .sum())
            }
            Op::Splat | Op::SplatU | Op::SplatQ => {
                for i in chunk {
                    out[i] = [q(0, c), 0, 0];
                }
            }
            Op::SetLane => {
                for i in chunk {
                    out[i] = [q(0, i), 0, 0];
                }
                let k = set_lane_index(c, w);
                out[c + k] = [q(1, c + k), 0, 0];
            }
            Op::Compress | Op::CompressU => {
                let mut k = c;
                for i in chunk {
                    if inp.m[i] {
                        out[k] = [q(0, i), 0, 0];
                        k += 1;
                    }
                }
            }
            Op::Expand | Op::ExpandU => {
                let mut k = c;
                for i in chunk {
                    if inp.m[i] {
                        out[i] = [q(0, k), 0, 0];
                        k += 1;
                    }
                }
            }
            _ => {
                for i in chunk {
                    out[i] = match op {
                        Op::Neg => fb(-f(0, i)),
                        Op::Abs => fb(f(0, i).abs()),
                        Op::Sqrt => fb(f(0, i).sqrt()),
                        Op::Floor => fb(f(0, i).floor()),
                        Op::Ceil => fb(f(0, i).ceil()),
                        Op::Trunc => fb(f(0, i).trunc()),
                        Op::Round => fb(f(0, i).round()),
                        Op::Add => fb(f(0, i) + f(1, i)),
                        Op::Sub => fb(f(0, i) - f(1, i)),
                        Op::Mul => fb(f(0, i) * f(1, i)),
                        Op::Div => fb(f(0, i) / f(1, i)),
                        Op::Min => fb(f(0, i).min(f(1, i))),
                        Op::Max => fb(f(0, i).max(f(1, i))),
                        Op::MinLt => fb(if f(0, i) < f(1, i) { f(0, i) } else { f(1, i) }),
                        Op::MaxGt => fb(if f(0, i) > f(1, i) { f(0, i) } else { f(1, i) }),
                        Op::Copysign => fb(f(0, i).copysign(f(1, i))),
                        Op::Clamp => fb({
                            let (x, lo, hi) = (f(0, i), f(1, i), f(2, i));
                            if lo <= hi {
                                x.clamp(lo, hi)
                            } else {
                                // (f32::clamp panics on these bounds; the lanes keep its rule)
                                let x = if x < lo { lo } else { x };
                                if x > hi {
                                    hi
                                } else {
                                    x
                                }
                            }
                        }),
                        Op::Eq => bb(f(0, i) == f(1, i)),
                        Op::Ne => bb(f(0, i) != f(1, i)),
                        Op::Lt => bb(f(0, i) < f(1, i)),
                        Op::Le => bb(f(0, i) <= f(1, i)),
                        Op::Gt => bb(f(0, i) > f(1, i)),
                        Op::Ge => bb(f(0, i) >= f(1, i)),
                        Op::IsNan => bb(f(0, i).is_nan()),
                        Op::IsFinite => bb(f(0, i).is_finite()),
                        Op::Select => fb(if inp.m[i] { f(0, i) } else { f(1, i) }),
                        Op::ToBits => ub(f(0, i).to_bits()),
                        Op::FromBits => fb(f32::from_bits(u(0, i))),
                        Op::ToI32 => ub(f(0, i) as i32 as u32),
                        Op::ToU32 => ub(f(0, i) as u32),
                        Op::FromI32 => fb(u(0, i) as i32 as f32),
                        Op::FromU32 => fb(u(0, i) as f32),
                        Op::UAdd => ub(u(0, i).wrapping_add(u(1, i))),
                        Op::USub => ub(u(0, i).wrapping_sub(u(1, i))),
                        Op::UMul => ub(u(0, i).wrapping_mul(u(1, i))),
                        Op::UAnd => ub(u(0, i) & u(1, i)),
                        Op::UOr => ub(u(0, i) | u(1, i)),
                        Op::UXor => ub(u(0, i) ^ u(1, i)),
                        Op::UShl => ub(u(0, i) << block_shift(i, 32)),
                        Op::UShr => ub(u(0, i) >> block_shift(i, 32)),
                        Op::UShlv => ub(u(0, i).checked_shl(u(1, i)).unwrap_or(0)),
                        Op::UShrv => ub(u(0, i).checked_shr(u(1, i)).unwrap_or(0)),
                        Op::URotr => ub(u(0, i).rotate_right(u(1, i))),
                        Op::UMin => ub(Ord::min(u(0, i), u(1, i))),
                        Op::UMax => ub(Ord::max(u(0, i), u(1, i))),
                        Op::UEq => bb(u(0, i) == u(1, i)),
                        Op::ULt => bb(u(0, i) < u(1, i)),
                        Op::UGt => bb(u(0, i) > u(1, i)),
                        Op::USelect => ub(if inp.m[i] { u(0, i) } else { u(1, i) }),
                        Op::QAdd => [q(0, i).wrapping_add(q(1, i)), 0, 0],
                        Op::QSub => [q(0, i).wrapping_sub(q(1, i)), 0, 0],
                        Op::QMul => [q(0, i).wrapping_mul(q(1, i)), 0, 0],
                        Op::QAnd => [q(0, i) & q(1, i), 0, 0],
                        Op::QOr => [q(0, i) | q(1, i), 0, 0],
                        Op::QXor => [q(0, i) ^ q(1, i), 0, 0],
                        Op::QShl => [q(0, i) << block_shift(i, 64), 0, 0],
                        Op::QShr => [q(0, i) >> block_shift(i, 64), 0, 0],
                        Op::QEq => bb(q(0, i) == q(1, i)),
                        Op::QSelect => [if inp.m[i] { q(0, i) } else { q(1, i) }, 0, 0],
                        Op::QFromU32 => [u(0, i) as u64, 0, 0],
                        Op::QLow32 => ub(q(0, i) as u32),
                        Op::QHigh32 => ub((q(0, i) >> 32) as u32),
                        Op::MAnd => bb(inp.m[i] & inp.m2[i]),
                        Op::MOr => bb(inp.m[i] | inp.m2[i]),
                        Op::MXor => bb(inp.m[i] ^ inp.m2[i]),
                        Op::MNot => bb(!inp.m[i]),
                        Op::MAndNot => bb(inp.m[i] & !inp.m2[i]),
                        Op::Index => ub((i - c) as u32),
                        Op::Gather => fb(if inp.m[i] {
                            inp.table_f[u(1, i) as usize]
                        } else {
                            0.0
                        }),
                        Op::GatherU => ub(if inp.m[i] {
                            inp.table_u[u(1, i) as usize]
                        } else {
                            0
                        }),
                        Op::VDot => fb(va(i).dot(vbv(i))),
                        Op::VCross => vb(va(i).cross(vbv(i))),
                        Op::VLength => fb(va(i).length()),
                        Op::VNormalize => vb(va(i) * (1.0 / va(i).length())),
                        Op::VNormalizeOrZero => vb(va(i).normalize_or_zero()),
                        Op::VMin => vb(va(i).min(vbv(i))),
                        Op::VMax => vb(va(i).max(vbv(i))),
                        Op::VMaxElement => fb(va(i).max_element()),
                        Op::VMinElement => fb(va(i).min_element()),
                        Op::VAbs => vb(va(i).abs()),
                        Op::VAdd => vb(va(i) + vbv(i)),
                        Op::VSub => vb(va(i) - vbv(i)),
                        Op::VMul => vb(va(i) * vbv(i)),
                        Op::VDiv => vb(va(i) / vbv(i)),
                        Op::VScale => vb(va(i) * f(3, i)),
                        Op::VDivScalar => vb(va(i) / f(3, i)),
                        Op::VNeg => vb(-va(i)),
                        Op::VEq => bb(va(i) == vbv(i)),
                        Op::VIsFinite => bb(va(i).is_finite()),
                        Op::VSelect => vb(if inp.m[i] { va(i) } else { vbv(i) }),
                        _ => unreachable!("{op:?} is chunked"),
                    }
                }
            }
        }
    }
    out
}

/// The lane computation of `op` on `inp`, chunk by chunk.
struct Eval<'a> {
    op: Op,
    inp: &'a Inputs,
}

impl LaneProgram for Eval<'_> {
    type Output = Out;
    #[inline(always)]
    fn run<L: Lanes>(self, l: L) -> Out {
        lanes_of(l, self.op, self.inp)
    }
}

#[inline(always)]
fn lanes_of<L: Lanes>(l: L, op: Op, inp: &Inputs) -> Out {
    let w = L::WIDTH;
    let mut out = vec![[0u64; 3]; N];
    for c in (0..N).step_by(w) {
        let fa = |k: usize| {
            let a: [f32; MAX_WIDTH] = std::array::from_fn(|i| {
                f32::from_bits(inp.v[k].get(c + i).copied().unwrap_or(0) as u32)
            });
            l.load(&a)
        };
        let ua = |k: usize| {
            let a: [u32; MAX_WIDTH] =
                std::array::from_fn(|i| inp.v[k].get(c + i).copied().unwrap_or(0) as u32);
            l.load_u32(&a)
        };
        let qa = |k: usize| {
            let a: [u64; MAX_WIDTH] =
                std::array::from_fn(|i| inp.v[k].get(c + i).copied().unwrap_or(0));
            l.load_u64(&a)
        };
        let bits_of = |m: &[bool]| -> u32 { (0..w).map(|i| (m[c + i] as u32) << i).sum() };
        let m = l.mask(bits_of(&inp.m));
        let m2 = l.mask(bits_of(&inp.m2));
        let v = |k: usize| V3::new(fa(k), fa(k + 1), fa(k + 2));
        let out = &mut out[c..c + w];
        // Results are read with `store`, each lane checked against `lane` (the mutation
        // sample's part 2 missed `U32x8x2::store` → `()`: no test stored u32 lanes).
        let put_f = |out: &mut [[u64; 3]], x: L::F| {
            let mut buf = [f32::NAN; MAX_WIDTH];
            x.store(&mut buf);
            for (i, o) in out.iter_mut().enumerate() {
                assert_eq!(
                    buf[i].to_bits(),
                    x.lane(i).to_bits(),
                    "{op:?}: store, lane {i}"
                );
                o[0] = buf[i].to_bits() as u64;
            }
        };
        let put_u = |out: &mut [[u64; 3]], x: L::U32| {
            let mut buf = [0xdead_beef_u32; MAX_WIDTH];
            x.store(&mut buf);
            for (i, o) in out.iter_mut().enumerate() {
                assert_eq!(buf[i], x.lane(i), "{op:?}: store, lane {i}");
                o[0] = buf[i] as u64;
            }
        };
        let put_q = |out: &mut [[u64; 3]], x: L::U64| {
            let mut buf = [0xdead_beef_dead_beef_u64; MAX_WIDTH];
            x.store(&mut buf);
            for (i, o) in out.iter_mut().enumerate() {
                assert_eq!(buf[i], x.lane(i), "{op:?}: store, lane {i}");
                o[0] = buf[i];
            }
        };
        let put_m = |out: &mut [[u64; 3]], x: L::M| {
            let b = x.bits();
            for (i, o) in out.iter_mut().enumerate() {
                o[0] = (b >> i & 1) as u64;
            }
        };
        let put_v = |out: &mut [[u64; 3]], x: V3<L::F>| {
            for (i, o) in out.iter_mut().enumerate() {
                let p = x.lane(i);
                *o = [
                    p.x.to_bits() as u64,
                    p.y.to_bits() as u64,
                    p.z.to_bits() as u64,
                ];
            }
        };
        match op {
            Op::Neg => put_f(out, -fa(0)),
            Op::Abs => put_f(out, fa(0).abs()),
            Op::Sqrt => put_f(out, fa(0).sqrt()),
            Op::Floor => put_f(out, fa(0).floor()),
            Op::Ceil => put_f(out, fa(0).ceil()),
            Op::Trunc => put_f(out, fa(0).trunc()),
            Op::Round => put_f(out, fa(0).round()),
            Op::Add => put_f(out, fa(0) + fa(1)),
            Op::Sub => put_f(out, fa(0) - fa(1)),
            Op::Mul => put_f(out, fa(0) * fa(1)),
            Op::Div => put_f(out, fa(0) / fa(1)),
            Op::Min => put_f(out, fa(0).min(fa(1))),
            Op::Max => put_f(out, fa(0).max(fa(1))),
            Op::MinLt => put_f(out, fa(0).min_lt(fa(1))),
            Op::MaxGt => put_f(out, fa(0).max_gt(fa(1))),
            Op::Copysign => put_f(out, fa(0).copysign(fa(1))),
            Op::Clamp => put_f(out, fa(0).clamp(fa(1), fa(2))),
            Op::Eq => put_m(out, fa(0).cmp_eq(fa(1))),
            Op::Ne => put_m(out, fa(0).cmp_ne(fa(1))),
            Op::Lt => put_m(out, fa(0).cmp_lt(fa(1))),
            Op::Le => put_m(out, fa(0).cmp_le(fa(1))),
            Op::Gt => put_m(out, fa(0).cmp_gt(fa(1))),
            Op::Ge => put_m(out, fa(0).cmp_ge(fa(1))),
            Op::IsNan => put_m(out, fa(0).is_nan()),
            Op::IsFinite => put_m(out, fa(0).is_finite()),
            Op::Select => put_f(out, L::F::select(m, fa(0), fa(1))),
            Op::ToBits => put_u(out, fa(0).to_bits()),
            Op::FromBits => put_f(out, L::F::from_bits(ua(0))),
            Op::ToI32 => put_u(out, fa(0).to_i32()),
            Op::ToU32 => put_u(out, fa(0).to_u32()),
            Op::FromI32 => put_f(out, L::F::from_i32(ua(0))),
            Op::FromU32 => put_f(out, L::F::from_u32(ua(0))),
            Op::UAdd => put_u(out, ua(0).wrapping_add(ua(1))),
            Op::USub => put_u(out, ua(0).wrapping_sub(ua(1))),
            Op::UMul => put_u(out, ua(0).wrapping_mul(ua(1))),
            Op::UAnd => put_u(out, ua(0) & ua(1)),
            Op::UOr => put_u(out, ua(0) | ua(1)),
            Op::UXor => put_u(out, ua(0) ^ ua(1)),
            Op::UShl => put_u(out, ua(0).shl(block_shift(c, 32))),
            Op::UShr => put_u(out, ua(0).shr(block_shift(c, 32))),
            Op::UShlv => put_u(out, ua(0).shlv(ua(1))),
            Op::UShrv => put_u(out, ua(0).shrv(ua(1))),
            Op::URotr => put_u(out, ua(0).rotate_right(ua(1))),
            Op::UMin => put_u(out, ua(0).min(ua(1))),
            Op::UMax => put_u(out, ua(0).max(ua(1))),
            Op::UEq => put_m(out, ua(0).cmp_eq(ua(1))),
            Op::ULt => put_m(out, ua(0).cmp_lt(ua(1))),
            Op::UGt => put_m(out, ua(0).cmp_gt(ua(1))),
            Op::USelect => put_u(out, L::U32::select(m, ua(0), ua(1))),
            Op::QAdd => put_q(out, qa(0).wrapping_add(qa(1))),
            Op::QSub => put_q(out, qa(0).wrapping_sub(qa(1))),
            Op::QMul => put_q(out, qa(0).wrapping_mul(qa(1))),
            Op::QAnd => put_q(out, qa(0) & qa(1)),
            Op::QOr => put_q(out, qa(0) | qa(1)),
            Op::QXor => put_q(out, qa(0) ^ qa(1)),
            Op::QShl => put_q(out, qa(0).shl(block_shift(c, 64))),
            Op::QShr => put_q(out, qa(0).shr(block_shift(c, 64))),
            Op::QEq => put_m(out, qa(0).cmp_eq(qa(1))),
            Op::QSelect => put_q(out, L::U64::select(m, qa(0), qa(1))),
            Op::QFromU32 => put_q(out, L::U64::from_u32(ua(0))),
            Op::QLow32 => put_u(out, qa(0).low32()),
            Op::QHigh32 => put_u(out, qa(0).high32()),
            Op::MAnd => put_m(out, m & m2),
            Op::MOr => put_m(out, m | m2),
            Op::MXor => put_m(out, m ^ m2),
            Op::MNot => put_m(out, !m),
            Op::MAndNot => put_m(out, m.and_not(m2)),
            Op::MAny => out[0][0] = m.any() as u64,
            Op::MAll => out[0][0] = m.all() as u64,
            Op::MCount => out[0][0] = m.count() as u64,
            Op::MBits => out[0][0] = m.bits() as u64,
            Op::Index => put_u(out, l.index()),
            Op::Splat => put_f(out, l.splat(f32::from_bits(inp.v[0][c] as u32))),
            Op::SplatU => put_u(out, l.splat_u32(inp.v[0][c] as u32)),
            Op::SplatQ => put_q(out, l.splat_u64(inp.v[0][c])),
            Op::SetLane => {
                let mut x = qa(0);
                let k = set_lane_index(c, w);
                x.set_lane(k, inp.v[1][c + k]);
                put_q(out, x)
            }
            Op::Gather => put_f(out, l.gather(&inp.table_f, ua(1), m)),
            Op::GatherU => put_u(out, l.gather_u32(&inp.table_u, ua(1), m)),
            Op::Compress => put_f(out, fa(0).compress(m)),
            Op::Expand => put_f(out, fa(0).expand(m)),
            Op::CompressU => put_u(out, ua(0).compress(m)),
            Op::ExpandU => put_u(out, ua(0).expand(m)),
            Op::VDot => put_f(out, v(0).dot(v(3))),
            Op::VCross => put_v(out, v(0).cross(v(3))),
            Op::VLength => put_f(out, v(0).length()),
            Op::VNormalize => put_v(out, v(0).normalize(l.splat(1.0))),
            Op::VNormalizeOrZero => put_v(out, v(0).normalize_or_zero(l.splat(1.0), l.splat(0.0))),
            Op::VMin => put_v(out, v(0).min(v(3))),
            Op::VMax => put_v(out, v(0).max(v(3))),
            Op::VMaxElement => put_f(out, v(0).max_element()),
            Op::VMinElement => put_f(out, v(0).min_element()),
            Op::VAbs => put_v(out, v(0).abs()),
            Op::VAdd => put_v(out, v(0) + v(3)),
            Op::VSub => put_v(out, v(0) - v(3)),
            Op::VMul => put_v(out, v(0) * v(3)),
            Op::VDiv => put_v(out, v(0) / v(3)),
            Op::VScale => put_v(out, v(0) * fa(3)),
            Op::VDivScalar => put_v(out, v(0) / fa(3)),
            Op::VNeg => put_v(out, -v(0)),
            Op::VEq => put_m(out, v(0).cmp_eq(v(3))),
            Op::VIsFinite => put_m(out, v(0).is_finite()),
            Op::VSelect => put_v(out, V3::select(m, v(0), v(3))),
        }
    }
    out
}

/// Operations whose f32 results are computed (not moved or masked): where such a result
/// is NaN, its sign and payload are not specified by Rust (RFC 3514, as LLVM may commute
/// the operands of an addition), and differ between two compilations of the same scalar
/// code (seen: glam's `dot` with two NaN terms, scalar against scalar). For these a NaN
/// result must be a NaN; every other result, and every result of the other operations
/// (negation, abs, copysign, selects, min_lt/max_gt, moves, bits), must be bit-identical.
fn arithmetic(op: Op) -> bool {
    use Op::*;
    matches!(
        op,
        Sqrt | Floor
            | Ceil
            | Trunc
            | Round
            | Add
            | Sub
            | Mul
            | Div
            | Min
            | Max
            | VDot
            | VCross
            | VLength
            | VNormalize
            | VNormalizeOrZero
            | VAdd
            | VSub
            | VMul
            | VDiv
            | VScale
            | VDivScalar
    )
}

/// Checks every operation on `backend`; panics at the first lane that differs.
fn check_backend(backend: Backend) {
    if !backend.supported() {
        eprintln!("{backend}: not supported by this processor, not checked");
        return;
    }
    let w = backend.width();
    for (k, &op) in OPS.iter().enumerate() {
        let inp = inputs(op, 0x5eed_0000 + k as u64);
        let want = reference(op, &inp, w);
        let got = dispatch(backend, Eval { op, inp: &inp }).expect("supported");
        let nan_payload_free = arithmetic(op);
        for i in 0..N {
            let same = got[i] == want[i]
                || nan_payload_free
                    && (0..3).all(|c| {
                        let (g, w) = (got[i][c] as u32, want[i][c] as u32);
                        g == w || f32::from_bits(g).is_nan() && f32::from_bits(w).is_nan()
                    });
            if !same {
                let show = |k: usize| format!("{:#x}", inp.v[k][i]);
                panic!(
                    "{backend} {op:?}: lane {i} gave {:x?}, the scalar operation {:x?} \
                     (inputs {} {} {} {} {} {}, mask {} {})",
                    got[i],
                    want[i],
                    show(0),
                    show(1),
                    show(2),
                    show(3),
                    show(4),
                    show(5),
                    inp.m[i],
                    inp.m2[i]
                );
            }
        }
    }
}

#[test]
fn the_op_list_is_complete() {
    // Every variant is in OPS once (a variant left out would never be checked).
    let names: std::collections::HashSet<String> = OPS.iter().map(|o| format!("{o:?}")).collect();
    assert_eq!(names.len(), OPS.len());
    assert_eq!(OPS.len(), Op::VSelect as usize + 1);
}

#[test]
fn scalar_ops_match_scalar() {
    check_backend(Backend::Scalar);
}

#[test]
fn portable_ops_match_scalar() {
    check_backend(Backend::Portable);
}

#[test]
fn avx2_ops_match_scalar() {
    check_backend(Backend::Avx2);
}

#[test]
fn avx512_ops_match_scalar() {
    check_backend(Backend::Avx512);
}

/// The processor of the project's machine (Zen 4) runs every backend: on it, the tests above
/// must not be skipped.
#[test]
#[cfg(target_arch = "x86_64")]
fn avx512_is_detected_where_the_cpu_has_it() {
    let has = is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx512dq");
    assert_eq!(Backend::Avx512.supported(), has);
    assert_eq!(Backend::best() == Backend::Avx512, has);
    if is_x86_feature_detected!("avx2") {
        assert!(Backend::Avx2.supported());
    }
}

struct GatherOutOfRange;

impl LaneProgram for GatherOutOfRange {
    type Output = f32;
    fn run<L: Lanes>(self, l: L) -> f32 {
        let table = [1.0f32; 4];
        // lane 0 active at index 4 of a 4-element table
        l.gather(&table, l.index().wrapping_add(l.splat_u32(4)), l.mask(1))
            .lane(0)
    }
}

#[test]
fn a_gather_out_of_bounds_panics_on_every_backend() {
    for b in Backend::all_supported() {
        let r = std::panic::catch_unwind(|| dispatch(b, GatherOutOfRange));
        assert!(r.is_err(), "{b}: an out-of-bounds gather must panic");
    }
}

#[test]
fn backend_names_round_trip() {
    for b in Backend::ALL {
        assert_eq!(Backend::from_name(b.name()), Some(b));
    }
    assert_eq!(Backend::from_name("avx"), None);
}

/// `Lanes::sin_cos` over `xs` (a multiple of 16 values), lane results as bits.
struct SinCos<'a>(&'a [f32]);

impl LaneProgram for SinCos<'_> {
    type Output = Vec<(u32, u32)>;
    #[inline(always)]
    fn run<L: Lanes>(self, l: L) -> Vec<(u32, u32)> {
        let mut out = Vec::with_capacity(self.0.len());
        for chunk in self.0.chunks(L::WIDTH) {
            let (s, c) = l.sin_cos(l.load(chunk));
            out.extend((0..L::WIDTH).map(|i| (s.lane(i).to_bits(), c.lane(i).to_bits())));
        }
        out
    }
}

#[test]
fn sin_cos_lanes_give_the_scalar_bits() {
    // Every 61st f32 of [−2π, 2π] (the renderer's angles), then random bit patterns and the
    // edges: the hand-off to std at 2¹⁹, quadrant boundaries, ±0, subnormals, ±∞, NaNs.
    let two_pi = std::f32::consts::TAU;
    let mut xs: Vec<f32> = Vec::new();
    let mut x = -two_pi;
    while x <= two_pi {
        xs.push(x);
        for _ in 0..61 {
            x = x.next_up();
        }
    }
    let mut rng = Pcg32::seed_from_u64(42);
    xs.extend((0..16 * 4096).map(|_| f32::from_bits(gen_f32(&mut rng))));
    let limit = crate::math::SIN_COS_LIMIT_F32;
    for v in [
        limit,
        limit.next_up(),
        limit.next_down(),
        1e30,
        3.0e5,
        1e-45,
        1e-40,
        0.0,
    ] {
        xs.extend([v, -v]);
    }
    for k in -64..=64 {
        let q = k as f32 * std::f32::consts::FRAC_PI_2;
        xs.extend([q, q.next_up(), q.next_down()]);
    }
    xs.extend([f32::INFINITY, f32::NEG_INFINITY, f32::NAN, -f32::NAN]);
    xs.resize(xs.len().next_multiple_of(16), 0.5);
    let want: Vec<(f32, f32)> = xs.iter().map(|&x| crate::math::sin_cosf(x)).collect();
    let same = |a: f32, b: u32| {
        let b = f32::from_bits(b);
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    };
    let mut backends = 0;
    for b in Backend::all_supported() {
        let got = dispatch(b, SinCos(&xs)).expect("supported");
        for ((x, w), g) in xs.iter().zip(&want).zip(&got) {
            assert!(
                same(w.0, g.0) && same(w.1, g.1),
                "{b}: sin_cos({x:e}) = ({:e}, {:e}), scalar ({:e}, {:e})",
                f32::from_bits(g.0),
                f32::from_bits(g.1),
                w.0,
                w.1
            );
        }
        backends += 1;
    }
    assert!(backends >= 2, "only {backends} backends ran");
}
