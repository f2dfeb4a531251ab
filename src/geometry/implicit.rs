//! Implicit surfaces given by an equation f(x, y, z) = 0 that the user
//! writes, such as `x^4 + y^4 + z^4 = 1`, found along a ray by interval
//! arithmetic (Mitchell 1990, "Robust Ray Intersection with Interval
//! Arithmetic"; Knoll et al. 2009, "Fast Ray Tracing of Arbitrary Implicit
//! Surfaces with Interval and Affine Arithmetic").
//!
//! The equation is compiled to a small stack program that is run three
//! ways: on intervals, on numbers, and on numbers with their gradient
//! (forward-mode dual numbers). Along a ray the program is run on the
//! interval of parameters [a, b]: the result encloses every value f takes
//! there, so where it excludes 0 there is no root, and the stretch is
//! dropped; otherwise it is halved, the nearer half first. A stretch
//! shorter than the tolerance holds the first root: bisected in numbers
//! where f changes sign between its ends, or taken where |f| at its middle
//! is within its gradient times its length (a double root, where the
//! surface touches the ray). So no root is missed, whatever f is, and the
//! first one is found first. The normal is the gradient.
//!
//! Intervals are computed in double precision and widened by an ulp after
//! each operation, which keeps them enclosures despite rounding.

use super::bounds::Aabb;
use super::ray::Ray;
use super::roots::bisect;
use super::sdf::RayCount;
use super::shape::LocalSurface;
use crate::sampling::warp::orthonormal_basis;
use glam::{DVec3, Vec2, Vec3};

/// The longest equation accepted, in characters.
pub const MAX_EQUATION_CHARS: usize = 4096;
/// The most operations of a compiled equation.
const MAX_OPS: usize = 1024;
/// The deepest the parser nests (parentheses, functions, powers).
const MAX_NESTING: usize = 64;
/// Interval evaluations one ray may take before it gives up.
pub const DEFAULT_MAX_EVALUATIONS: u32 = 4096;
/// Root tolerance as a fraction of the bounds' largest extent.
const RELATIVE_TOLERANCE: f64 = 1e-6;

/// An operation of the stack program.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Op {
    X,
    Y,
    Z,
    Const(f64),
    Add,
    Sub,
    Mul,
    Div,
    Neg,
    /// An integer power.
    PowInt(i32),
    /// A power with a real exponent (base ≥ 0).
    Pow,
    Sqrt,
    Abs,
    Sin,
    Cos,
    Exp,
    Ln,
    Min,
    Max,
}

/// A compiled equation f(x, y, z) = 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Equation {
    ops: Vec<Op>,
    /// Values on the stack at most.
    depth: usize,
}

/// An error in an equation: what, and at which character (from 1).
#[derive(Clone, Debug, PartialEq)]
pub struct EquationError {
    /// Column of the character, from 1.
    pub column: usize,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for EquationError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "column {} of the equation: {}", self.column, self.message)
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Num(f64),
    Ident(String),
    Sym(char),
    End,
}

struct Parser {
    tokens: Vec<(Token, usize)>,
    pos: usize,
    ops: Vec<Op>,
    nesting: usize,
}

fn tokenize(text: &str) -> Result<Vec<(Token, usize)>, EquationError> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let col = i + 1;
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit() || c == '.' {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            // An exponent: 1e-3, 2.5E4.
            if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                let mut j = i + 1;
                if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
                    j += 1;
                }
                if j < chars.len() && chars[j].is_ascii_digit() {
                    i = j;
                    while i < chars.len() && chars[i].is_ascii_digit() {
                        i += 1;
                    }
                }
            }
            let s: String = chars[start..i].iter().collect();
            let v = s.parse::<f64>().map_err(|_| EquationError {
                column: col,
                message: format!("\"{s}\" is not a number"),
            })?;
            out.push((Token::Num(v), col));
        } else if c.is_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push((Token::Ident(chars[start..i].iter().collect()), col));
        } else if "+-*/^(),".contains(c) {
            out.push((Token::Sym(c), col));
            i += 1;
        } else {
            return Err(EquationError {
                column: col,
                message: format!("unexpected character '{c}'"),
            });
        }
    }
    out.push((Token::End, chars.len() + 1));
    Ok(out)
}

const FUNCTIONS: [&str; 9] = ["sqrt", "abs", "sin", "cos", "exp", "ln", "min", "max", "pow"];

impl Parser {
    fn peek(&self) -> &Token {
        &self.tokens[self.pos].0
    }

    fn column(&self) -> usize {
        self.tokens[self.pos].1
    }

    fn error(&self, message: impl Into<String>) -> EquationError {
        EquationError {
            column: self.column(),
            message: message.into(),
        }
    }

    fn emit(&mut self, op: Op) -> Result<(), EquationError> {
        if self.ops.len() >= MAX_OPS {
            return Err(self.error(format!("the equation is too long (more than {MAX_OPS} operations)")));
        }
        self.ops.push(op);
        Ok(())
    }

    fn expect(&mut self, c: char) -> Result<(), EquationError> {
        if *self.peek() == Token::Sym(c) {
            self.pos += 1;
            Ok(())
        } else {
            Err(self.error(format!("expected '{c}'")))
        }
    }

    fn nest(&mut self) -> Result<(), EquationError> {
        self.nesting += 1;
        if self.nesting > MAX_NESTING {
            return Err(self.error(format!("the equation nests more than {MAX_NESTING} deep")));
        }
        Ok(())
    }

    /// sum := product (('+' | '-') product)*
    fn sum(&mut self) -> Result<(), EquationError> {
        self.product()?;
        loop {
            let op = match self.peek() {
                Token::Sym('+') => Op::Add,
                Token::Sym('-') => Op::Sub,
                _ => return Ok(()),
            };
            self.pos += 1;
            self.product()?;
            self.emit(op)?;
        }
    }

    /// product := unary (('*' | '/') unary | implicit product)*
    fn product(&mut self) -> Result<(), EquationError> {
        self.unary()?;
        loop {
            let op = match self.peek() {
                Token::Sym('*') => Op::Mul,
                Token::Sym('/') => Op::Div,
                // "2x", "3 x y", "2(x + 1)": juxtaposition multiplies.
                Token::Num(_) | Token::Ident(_) | Token::Sym('(') => {
                    self.unary()?;
                    self.emit(Op::Mul)?;
                    continue;
                }
                _ => return Ok(()),
            };
            self.pos += 1;
            self.unary()?;
            self.emit(op)?;
        }
    }

    /// unary := '-' unary | '+' unary | power
    fn unary(&mut self) -> Result<(), EquationError> {
        match self.peek() {
            Token::Sym('-') => {
                self.pos += 1;
                self.nest()?;
                self.unary()?;
                self.nesting -= 1;
                self.emit(Op::Neg)
            }
            Token::Sym('+') => {
                self.pos += 1;
                self.nest()?;
                self.unary()?;
                self.nesting -= 1;
                Ok(())
            }
            _ => self.power(),
        }
    }

    /// power := atom ('^' unary)?   (right-associative: 2^3^2 = 2^9)
    fn power(&mut self) -> Result<(), EquationError> {
        self.atom()?;
        if *self.peek() != Token::Sym('^') {
            return Ok(());
        }
        self.pos += 1;
        self.nest()?;
        // An integer exponent written as such is an exact power, defined
        // for negative bases too.
        let start = self.ops.len();
        self.unary()?;
        self.nesting -= 1;
        if let (true, Some(&Op::Const(e))) = (self.ops.len() == start + 1, self.ops.get(start)) {
            if e.fract() == 0.0 && e.abs() <= 64.0 {
                self.ops.truncate(start);
                return self.emit(Op::PowInt(e as i32));
            }
        }
        self.emit(Op::Pow)
    }

    fn atom(&mut self) -> Result<(), EquationError> {
        let (token, column) = self.tokens[self.pos].clone();
        match token {
            Token::Num(v) => {
                self.pos += 1;
                self.emit(Op::Const(v))
            }
            Token::Sym('(') => {
                self.pos += 1;
                self.nest()?;
                self.sum()?;
                self.nesting -= 1;
                self.expect(')')
            }
            Token::Ident(name) => {
                self.pos += 1;
                match name.as_str() {
                    "x" => self.emit(Op::X),
                    "y" => self.emit(Op::Y),
                    "z" => self.emit(Op::Z),
                    "pi" => self.emit(Op::Const(std::f64::consts::PI)),
                    "e" => self.emit(Op::Const(std::f64::consts::E)),
                    f if FUNCTIONS.contains(&f) => {
                        self.expect('(')?;
                        self.nest()?;
                        self.sum()?;
                        let two = matches!(f, "min" | "max" | "pow");
                        if two {
                            self.expect(',')?;
                            self.sum()?;
                        }
                        self.nesting -= 1;
                        self.expect(')')?;
                        self.emit(match f {
                            "sqrt" => Op::Sqrt,
                            "abs" => Op::Abs,
                            "sin" => Op::Sin,
                            "cos" => Op::Cos,
                            "exp" => Op::Exp,
                            "ln" => Op::Ln,
                            "min" => Op::Min,
                            "max" => Op::Max,
                            _ => Op::Pow,
                        })
                    }
                    other => Err(EquationError {
                        column,
                        message: format!(
                            "unknown name \"{other}\" (the variables are x, y and z; the constants pi and e; the functions {})",
                            FUNCTIONS.join(", ")
                        ),
                    }),
                }
            }
            Token::End => Err(self.error("the equation ends too soon")),
            Token::Sym(c) => Err(self.error(format!("unexpected '{c}'"))),
        }
    }
}

impl Equation {
    /// Compiles `text`: an expression f, meaning f = 0, or an equation
    /// `lhs = rhs`, meaning lhs − rhs = 0.
    pub fn parse(text: &str) -> Result<Equation, EquationError> {
        if text.chars().count() > MAX_EQUATION_CHARS {
            return Err(EquationError {
                column: MAX_EQUATION_CHARS,
                message: format!("the equation is longer than {MAX_EQUATION_CHARS} characters"),
            });
        }
        let sides: Vec<&str> = text.split('=').collect();
        if sides.len() > 2 {
            let second = text
                .match_indices('=')
                .nth(1)
                .map_or(0, |(i, _)| text[..i].chars().count());
            return Err(EquationError {
                column: second + 1,
                message: "an equation has at most one '='".into(),
            });
        }
        let mut ops = Vec::new();
        let mut offset = 0;
        for (k, side) in sides.iter().enumerate() {
            let mut tokens = tokenize(side)?;
            for t in &mut tokens {
                t.1 += offset;
            }
            let mut p = Parser {
                tokens,
                pos: 0,
                ops: std::mem::take(&mut ops),
                nesting: 0,
            };
            if *p.peek() == Token::End {
                return Err(p.error("an empty side"));
            }
            p.sum()?;
            if *p.peek() != Token::End {
                return Err(p.error("unexpected text after the expression"));
            }
            ops = p.ops;
            if k == 1 {
                ops.push(Op::Sub);
            }
            offset += side.chars().count() + 1;
        }
        let mut depth = 0usize;
        let mut most = 0;
        for op in &ops {
            match op {
                Op::X | Op::Y | Op::Z | Op::Const(_) => depth += 1,
                Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Pow | Op::Min | Op::Max => depth -= 1,
                _ => {}
            }
            most = most.max(depth);
        }
        if !ops.iter().any(|op| matches!(op, Op::X | Op::Y | Op::Z)) {
            return Err(EquationError {
                column: 1,
                message: "the equation does not depend on x, y or z".into(),
            });
        }
        Ok(Equation { ops, depth: most })
    }

    /// Runs the program over values of type `T`.
    #[inline]
    fn run<T: Arith>(&self, x: T, y: T, z: T, stack: &mut Vec<T>) -> T {
        stack.clear();
        for op in &self.ops {
            let v = match *op {
                Op::X => x,
                Op::Y => y,
                Op::Z => z,
                Op::Const(c) => T::constant(c),
                Op::Neg => stack.pop().expect("compiled").neg(),
                Op::PowInt(n) => stack.pop().expect("compiled").powi(n),
                Op::Sqrt => stack.pop().expect("compiled").sqrt(),
                Op::Abs => stack.pop().expect("compiled").abs(),
                Op::Sin => stack.pop().expect("compiled").sin(),
                Op::Cos => stack.pop().expect("compiled").cos(),
                Op::Exp => stack.pop().expect("compiled").exp(),
                Op::Ln => stack.pop().expect("compiled").ln(),
                binary => {
                    let b = stack.pop().expect("compiled");
                    let a = stack.pop().expect("compiled");
                    match binary {
                        Op::Add => a.add(b),
                        Op::Sub => a.sub(b),
                        Op::Mul => a.mul(b),
                        Op::Div => a.div(b),
                        Op::Pow => a.pow(b),
                        Op::Min => a.min(b),
                        _ => a.max(b),
                    }
                }
            };
            stack.push(v);
        }
        stack.pop().expect("compiled")
    }

    /// f at `p`.
    pub fn value(&self, p: DVec3) -> f64 {
        let mut stack = Vec::with_capacity(self.depth);
        self.run(p.x, p.y, p.z, &mut stack)
    }

    /// f and its gradient at `p`.
    pub fn value_and_gradient(&self, p: DVec3) -> (f64, DVec3) {
        let mut stack = Vec::with_capacity(self.depth);
        let d = self.run(
            Dual::var(p.x, DVec3::X),
            Dual::var(p.y, DVec3::Y),
            Dual::var(p.z, DVec3::Z),
            &mut stack,
        );
        (d.v, d.g)
    }

    /// An enclosure of f over the box `x × y × z`.
    pub fn enclose(&self, x: Interval, y: Interval, z: Interval) -> Interval {
        let mut stack = Vec::with_capacity(self.depth);
        self.run(x, y, z, &mut stack)
    }
}

/// Arithmetic that the stack program runs on.
trait Arith: Copy {
    fn constant(c: f64) -> Self;
    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn div(self, o: Self) -> Self;
    fn neg(self) -> Self;
    fn powi(self, n: i32) -> Self;
    fn pow(self, e: Self) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn sin(self) -> Self;
    fn cos(self) -> Self;
    fn exp(self) -> Self;
    fn ln(self) -> Self;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
}

impl Arith for f64 {
    fn constant(c: f64) -> Self {
        c
    }
    fn add(self, o: Self) -> Self {
        self + o
    }
    fn sub(self, o: Self) -> Self {
        self - o
    }
    fn mul(self, o: Self) -> Self {
        self * o
    }
    fn div(self, o: Self) -> Self {
        self / o
    }
    fn neg(self) -> Self {
        -self
    }
    fn powi(self, n: i32) -> Self {
        f64::powi(self, n)
    }
    fn pow(self, e: Self) -> Self {
        if self < 0.0 { f64::NAN } else { f64::powf(self, e) }
    }
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    fn abs(self) -> Self {
        f64::abs(self)
    }
    fn sin(self) -> Self {
        f64::sin(self)
    }
    fn cos(self) -> Self {
        f64::cos(self)
    }
    fn exp(self) -> Self {
        f64::exp(self)
    }
    fn ln(self) -> Self {
        f64::ln(self)
    }
    fn min(self, o: Self) -> Self {
        f64::min(self, o)
    }
    fn max(self, o: Self) -> Self {
        f64::max(self, o)
    }
}

/// A number and its gradient with respect to (x, y, z).
#[derive(Clone, Copy, Debug)]
struct Dual {
    v: f64,
    g: DVec3,
}

impl Dual {
    fn var(v: f64, g: DVec3) -> Dual {
        Dual { v, g }
    }
    /// g(self) with derivative `d` = g′(self.v).
    fn chain(self, v: f64, d: f64) -> Dual {
        Dual { v, g: self.g * d }
    }
}

impl Arith for Dual {
    fn constant(c: f64) -> Self {
        Dual { v: c, g: DVec3::ZERO }
    }
    fn add(self, o: Self) -> Self {
        Dual {
            v: self.v + o.v,
            g: self.g + o.g,
        }
    }
    fn sub(self, o: Self) -> Self {
        Dual {
            v: self.v - o.v,
            g: self.g - o.g,
        }
    }
    fn mul(self, o: Self) -> Self {
        Dual {
            v: self.v * o.v,
            g: self.g * o.v + o.g * self.v,
        }
    }
    fn div(self, o: Self) -> Self {
        Dual {
            v: self.v / o.v,
            g: (self.g * o.v - o.g * self.v) / (o.v * o.v),
        }
    }
    fn neg(self) -> Self {
        Dual { v: -self.v, g: -self.g }
    }
    fn powi(self, n: i32) -> Self {
        let d = if n == 0 { 0.0 } else { n as f64 * self.v.powi(n - 1) };
        self.chain(self.v.powi(n), d)
    }
    fn pow(self, e: Self) -> Self {
        if self.v < 0.0 {
            return Dual::constant(f64::NAN);
        }
        let v = self.v.powf(e.v);
        // d(a^b) = b·a^(b−1)·da + a^b·ln a·db
        let da = if self.v > 0.0 {
            e.v * self.v.powf(e.v - 1.0)
        } else {
            0.0
        };
        let db = if self.v > 0.0 { v * self.v.ln() } else { 0.0 };
        Dual {
            v,
            g: self.g * da + e.g * db,
        }
    }
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, 0.5 / s)
    }
    fn abs(self) -> Self {
        self.chain(self.v.abs(), if self.v < 0.0 { -1.0 } else { 1.0 })
    }
    fn sin(self) -> Self {
        self.chain(self.v.sin(), self.v.cos())
    }
    fn cos(self) -> Self {
        self.chain(self.v.cos(), -self.v.sin())
    }
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    fn ln(self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v)
    }
    fn min(self, o: Self) -> Self {
        if self.v <= o.v { self } else { o }
    }
    fn max(self, o: Self) -> Self {
        if self.v >= o.v { self } else { o }
    }
}

/// A closed interval [lo, hi] of numbers; empty where lo > hi (a function
/// undefined over the whole of its argument, such as √ of negatives).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

const EMPTY: Interval = Interval {
    lo: f64::INFINITY,
    hi: f64::NEG_INFINITY,
};
const EVERYTHING: Interval = Interval {
    lo: f64::NEG_INFINITY,
    hi: f64::INFINITY,
};

impl Interval {
    /// [lo, hi].
    pub fn new(lo: f64, hi: f64) -> Interval {
        Interval { lo, hi }
    }

    /// Whether it holds no number.
    pub fn is_empty(&self) -> bool {
        self.lo
            .partial_cmp(&self.hi)
            .is_none_or(|o| o == std::cmp::Ordering::Greater)
    }

    /// Whether it holds `x`.
    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    /// Rounded outwards by an ulp at each end, so that an operation's
    /// rounding cannot make it miss a value.
    #[inline]
    fn widened(lo: f64, hi: f64) -> Interval {
        if lo.is_nan() || hi.is_nan() {
            // NaN from ∞ − ∞ or 0·∞: nothing is known.
            return EVERYTHING;
        }
        // At least an ulp outwards (f64::next_down/next_up need a newer
        // Rust than trazo's minimum).
        Interval {
            lo: lo - (lo.abs() * f64::EPSILON + f64::MIN_POSITIVE),
            hi: hi + (hi.abs() * f64::EPSILON + f64::MIN_POSITIVE),
        }
    }

    fn either_empty(self, o: Interval) -> bool {
        self.is_empty() || o.is_empty()
    }

    /// Whether the interval holds a point where a function of period 2π
    /// peaks at `phase` (mod 2π).
    fn holds_phase(&self, phase: f64) -> bool {
        let two_pi = std::f64::consts::TAU;
        let k = ((self.lo - phase) / two_pi).ceil();
        phase + k * two_pi <= self.hi
    }
}

impl Arith for Interval {
    fn constant(c: f64) -> Self {
        Interval { lo: c, hi: c }
    }
    fn add(self, o: Self) -> Self {
        if self.either_empty(o) {
            return EMPTY;
        }
        Interval::widened(self.lo + o.lo, self.hi + o.hi)
    }
    fn sub(self, o: Self) -> Self {
        if self.either_empty(o) {
            return EMPTY;
        }
        Interval::widened(self.lo - o.hi, self.hi - o.lo)
    }
    fn mul(self, o: Self) -> Self {
        if self.either_empty(o) {
            return EMPTY;
        }
        let p = [self.lo * o.lo, self.lo * o.hi, self.hi * o.lo, self.hi * o.hi];
        if p.iter().any(|v| v.is_nan()) {
            // 0·∞: an unbounded factor times one that holds 0.
            return EVERYTHING;
        }
        Interval::widened(
            p.iter().copied().fold(f64::INFINITY, f64::min),
            p.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        )
    }
    fn div(self, o: Self) -> Self {
        if self.either_empty(o) {
            return EMPTY;
        }
        if o.contains(0.0) {
            return EVERYTHING;
        }
        self.mul(Interval::widened(1.0 / o.hi, 1.0 / o.lo))
    }
    fn neg(self) -> Self {
        if self.is_empty() {
            return EMPTY;
        }
        Interval {
            lo: -self.hi,
            hi: -self.lo,
        }
    }
    fn powi(self, n: i32) -> Self {
        if self.is_empty() {
            return EMPTY;
        }
        if n == 0 {
            return Interval::constant(1.0);
        }
        if n < 0 {
            return Interval::constant(1.0).div(self.powi(-n));
        }
        let (a, b) = (self.lo.powi(n), self.hi.powi(n));
        if n % 2 == 1 || self.lo >= 0.0 {
            Interval::widened(a, b)
        } else if self.hi <= 0.0 {
            Interval::widened(b, a)
        } else {
            Interval::widened(0.0, a.max(b))
        }
    }
    fn pow(self, e: Self) -> Self {
        // a^b = exp(b·ln a), for a ≥ 0.
        self.ln().mul(e).exp()
    }
    fn sqrt(self) -> Self {
        if self.is_empty() || self.hi < 0.0 {
            return EMPTY;
        }
        Interval::widened(self.lo.max(0.0).sqrt(), self.hi.sqrt())
    }
    fn abs(self) -> Self {
        if self.is_empty() {
            return EMPTY;
        }
        if self.lo >= 0.0 {
            self
        } else if self.hi <= 0.0 {
            self.neg()
        } else {
            Interval {
                lo: 0.0,
                hi: (-self.lo).max(self.hi),
            }
        }
    }
    fn sin(self) -> Self {
        if self.is_empty() {
            return EMPTY;
        }
        if self.hi - self.lo >= std::f64::consts::TAU || (self.hi - self.lo).is_nan() {
            return Interval::new(-1.0, 1.0);
        }
        let (a, b) = (self.lo.sin(), self.hi.sin());
        let hi = if self.holds_phase(std::f64::consts::FRAC_PI_2) {
            1.0
        } else {
            a.max(b)
        };
        let lo = if self.holds_phase(-std::f64::consts::FRAC_PI_2) {
            -1.0
        } else {
            a.min(b)
        };
        let w = Interval::widened(lo, hi);
        Interval::new(w.lo.max(-1.0), w.hi.min(1.0))
    }
    fn cos(self) -> Self {
        if self.is_empty() {
            return EMPTY;
        }
        Interval::new(
            self.lo + std::f64::consts::FRAC_PI_2,
            self.hi + std::f64::consts::FRAC_PI_2,
        )
        .widened_self()
        .sin()
    }
    fn exp(self) -> Self {
        if self.is_empty() {
            return EMPTY;
        }
        Interval::widened(self.lo.exp(), self.hi.exp())
    }
    fn ln(self) -> Self {
        if self.is_empty() || self.hi <= 0.0 {
            return EMPTY;
        }
        let lo = if self.lo <= 0.0 {
            f64::NEG_INFINITY
        } else {
            self.lo.ln()
        };
        Interval::widened(lo, self.hi.ln())
    }
    fn min(self, o: Self) -> Self {
        if self.either_empty(o) {
            return EMPTY;
        }
        Interval::new(self.lo.min(o.lo), self.hi.min(o.hi))
    }
    fn max(self, o: Self) -> Self {
        if self.either_empty(o) {
            return EMPTY;
        }
        Interval::new(self.lo.max(o.lo), self.hi.max(o.hi))
    }
}

impl Interval {
    fn widened_self(self) -> Interval {
        Interval::widened(self.lo, self.hi)
    }
}

/// The surface f = 0 of an equation within a box.
#[derive(Clone, Debug, PartialEq)]
pub struct ImplicitSurface {
    equation: Equation,
    bounds: Aabb,
    /// Root tolerance, object units.
    tolerance: f64,
    max_evaluations: u32,
    give_ups: RayCount,
    origin: Option<String>,
}

impl ImplicitSurface {
    /// The surface of `equation` within `bounds` (which must have volume).
    pub fn new(equation: Equation, bounds: Aabb, max_evaluations: u32) -> Result<ImplicitSurface, String> {
        if !(bounds.min.is_finite() && bounds.max.is_finite()) || bounds.min.cmpge(bounds.max).any() {
            return Err(format!(
                "the bounds must be a box with min below max on every axis, got {} to {}",
                bounds.min, bounds.max
            ));
        }
        if !(16..=1 << 20).contains(&max_evaluations) {
            return Err(format!(
                "max_evaluations must be between 16 and {}, got {max_evaluations}",
                1 << 20
            ));
        }
        let extent = bounds.extent().max_element() as f64;
        Ok(ImplicitSurface {
            equation,
            bounds,
            tolerance: extent * RELATIVE_TOLERANCE,
            max_evaluations,
            give_ups: RayCount::default(),
            origin: None,
        })
    }

    /// The shape, named by where the scene defines it.
    pub fn with_origin(mut self, origin: String) -> ImplicitSurface {
        self.origin = Some(origin);
        self
    }

    /// Where the scene defines the shape, if known.
    pub fn origin(&self) -> Option<&str> {
        self.origin.as_deref()
    }

    /// Object-space bounds.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Rays that gave up (ran out of evaluations) since the shape was made.
    pub fn give_ups(&self) -> u64 {
        self.give_ups.get()
    }

    /// Interval evaluations a ray may take.
    pub fn max_evaluations(&self) -> u32 {
        self.max_evaluations
    }

    /// The first root of f along the ray (object space) within its
    /// interval and the bounds. Its interval evaluations count in the
    /// `steps` image.
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let mut evaluations = 0;
        let hit = self.search(ray, &mut evaluations);
        super::sdf::add_steps(evaluations as u64);
        hit
    }

    fn search(&self, ray: &Ray, evaluations: &mut u32) -> Option<f32> {
        let (t0, t1) = self.bounds.intersect(ray, ray.dir.recip())?;
        let o = ray.origin.as_dvec3();
        let d = ray.dir.as_dvec3();
        let len = d.length();
        if len.is_nan() || len <= 0.0 {
            return None;
        }
        // Parameter tolerance for the root: the distance tolerance along
        // the ray.
        let tol = self.tolerance / len;
        let along = |a: f64, b: f64| {
            let axis = |o: f64, d: f64| {
                let (p, q) = (o + a * d, o + b * d);
                Interval::widened(p.min(q), p.max(q))
            };
            self.equation.enclose(axis(o.x, d.x), axis(o.y, d.y), axis(o.z, d.z))
        };
        let value = |t: f64| self.equation.value(o + d * t);
        let mut stack: Vec<(f64, f64)> = Vec::with_capacity(64);
        stack.push((t0 as f64, t1 as f64));
        let t_min = ray.t_min as f64;
        while let Some((a, b)) = stack.pop() {
            *evaluations += 1;
            if *evaluations > self.max_evaluations {
                self.give_ups.add();
                return None;
            }
            let f = along(a, b);
            if !f.contains(0.0) {
                continue;
            }
            if b - a > tol {
                let m = 0.5 * (a + b);
                // The far half first onto the stack: the near one is
                // searched first.
                stack.push((m, b));
                stack.push((a, m));
                continue;
            }
            let (fa, fb) = (value(a), value(b));
            if fa == 0.0 && a > t_min {
                return Some(a as f32);
            }
            if (fa < 0.0) != (fb < 0.0) && !fa.is_nan() && !fb.is_nan() {
                let t = bisect(&value, a, b, fa);
                if t > t_min {
                    return Some(t as f32);
                }
                continue;
            }
            // No sign change in a stretch the enclosure cannot rule out:
            // a root where the surface touches the ray if f is as small as
            // its slope over the stretch allows.
            let m = 0.5 * (a + b);
            let (fm, g) = self.equation.value_and_gradient(o + d * m);
            if fm.abs() <= g.dot(d).abs() * (b - a) + 1e-12 * g.length() && m > t_min {
                return Some(m as f32);
            }
        }
        None
    }

    /// The surface at a point found by [`ImplicitSurface::intersect`]: the
    /// gradient as the normal (f > 0 outside), (u, v) spherical around the
    /// bounds' centre.
    pub fn surface(&self, p: Vec3) -> LocalSurface {
        let (_, g) = self.equation.value_and_gradient(p.as_dvec3());
        let n = g.as_vec3().try_normalize().filter(|n| n.is_finite()).unwrap_or(Vec3::Z);
        let (dpdu, dpdv) = orthonormal_basis(n);
        let c = (p - self.bounds.centroid()).normalize_or(Vec3::Y);
        let uv = Vec2::new(
            c.z.atan2(c.x) * (0.5 * std::f32::consts::FRAC_1_PI) + 0.5,
            c.y.clamp(-1.0, 1.0).acos() * std::f32::consts::FRAC_1_PI,
        );
        // Rays leaving the surface start beyond the root tolerance.
        let offset = (8.0 * self.tolerance) as f32;
        LocalSurface {
            p,
            p_error: Vec3::splat(offset) + p.abs() * (8.0 * f32::EPSILON),
            n,
            uv,
            dpdu,
            dpdv,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    fn eq(s: &str) -> Equation {
        Equation::parse(s).unwrap()
    }

    #[test]
    fn equations_parse_and_evaluate() {
        let p = DVec3::new(0.5, -2.0, 3.0);
        let cases = [
            ("x^2 + y^2 + z^2 - 1", 0.25 + 4.0 + 9.0 - 1.0),
            ("x^2 + y^2 + z^2 = 1", 0.25 + 4.0 + 9.0 - 1.0),
            ("2x - 3 y z", 1.0 + 18.0),
            ("-x^2", -0.25),
            ("2^3^2 + 0*x", 512.0),
            ("sqrt(z + 1) * abs(y) / 4", 1.0),
            ("min(x, y) + max(x, z) + pow(z, 0.5)", -2.0 + 3.0 + 3f64.sqrt()),
            ("sin(pi x) + cos(0*y) + exp(0*z) + ln(e)", 1.0 + 1.0 + 1.0 + 1.0),
            ("1.5e1 x", 7.5),
            ("(x + 1)(y - 1)", 1.5 * -3.0),
        ];
        for (text, expected) in cases {
            let v = eq(text).value(p);
            assert!((v - expected).abs() < 1e-12, "{text}: {v} vs {expected}");
        }
    }

    #[test]
    fn bad_equations_name_the_column() {
        let cases = [
            ("x^2 + y^2 +", 12, "ends"),
            ("x + w", 5, "unknown name \"w\""),
            ("x ** 2", 4, "unexpected '*'"),
            ("x = y = z", 7, "one '='"),
            ("1 + 2", 1, "does not depend"),
            ("sin x", 5, "expected '('"),
            ("x $ 2", 3, "unexpected character"),
            ("(x + 1", 7, "expected ')'"),
            ("x = ", 5, "empty side"),
        ];
        for (text, column, what) in cases {
            let e = Equation::parse(text).unwrap_err();
            assert!(e.message.contains(what), "{text}: {e}");
            assert_eq!(e.column, column, "{text}: {e}");
        }
        let deep = format!("{}x{}", "(".repeat(100), ")".repeat(100));
        assert!(Equation::parse(&deep).unwrap_err().message.contains("nests"));
    }

    #[test]
    fn gradients_are_the_derivatives() {
        let e = eq("x^3 y - sin(z) x + sqrt(x^2 + 1) + exp(y) / (z^2 + 2) + pow(x^2 + 1, 1.5)");
        let mut rng = Pcg32::new(4, 4);
        for _ in 0..100 {
            let p = DVec3::new(
                rng.next_f64() * 4.0 - 2.0,
                rng.next_f64() * 4.0 - 2.0,
                rng.next_f64() * 4.0 - 2.0,
            );
            let (v, g) = e.value_and_gradient(p);
            assert_eq!(v, e.value(p));
            let h = 1e-6;
            let num = DVec3::new(
                e.value(p + DVec3::X * h) - e.value(p - DVec3::X * h),
                e.value(p + DVec3::Y * h) - e.value(p - DVec3::Y * h),
                e.value(p + DVec3::Z * h) - e.value(p - DVec3::Z * h),
            ) / (2.0 * h);
            assert!((g - num).length() < 1e-5 * (1.0 + g.length()), "{p}: {g} vs {num}");
        }
    }

    #[test]
    fn intervals_enclose_every_value() {
        let e =
            eq("x^4 - 3 x^2 y + sin(3 z) / (y^2 + 1) - sqrt(abs(x z)) + min(x, y) * max(z, 1) + exp(-x^2) + cos(x y)");
        let mut rng = Pcg32::new(8, 1);
        for _ in 0..300 {
            let mut corner = || {
                let a = rng.next_f64() * 6.0 - 3.0;
                let w = rng.next_f64() * rng.next_f64() * 3.0;
                Interval::new(a, a + w)
            };
            let (x, y, z) = (corner(), corner(), corner());
            let f = e.enclose(x, y, z);
            for _ in 0..50 {
                let mut pick = |i: Interval| i.lo + (i.hi - i.lo) * rng.next_f64();
                let p = DVec3::new(pick(x), pick(y), pick(z));
                let v = e.value(p);
                assert!(f.contains(v), "{v} outside [{}, {}]", f.lo, f.hi);
            }
        }
    }

    fn shape(text: &str, half: f32) -> ImplicitSurface {
        ImplicitSurface::new(eq(text), Aabb::new(Vec3::splat(-half), Vec3::splat(half)), 4096).unwrap()
    }

    #[test]
    fn rays_find_the_first_root() {
        // The unit sphere as an equation, against the exact answer.
        let s = shape("x^2 + y^2 + z^2 = 1", 1.5);
        let mut rng = Pcg32::new(2, 3);
        for _ in 0..300 {
            let o = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 4.0);
            let target = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 0.0);
            let ray = Ray::new(o, (target - o) * 0.7);
            let t = s.intersect(&ray).expect("hits");
            let p = ray.at(t);
            assert!((p.length() - 1.0).abs() < 1e-5, "{}", p.length());
            assert!(s.surface(p).n.dot(p) > 0.9999);
        }
        // From inside, the exit.
        let t = s.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).unwrap();
        assert!((t - 1.0).abs() < 1e-5);
        // A torus: a ray down its axis misses; one through the tube meets
        // its near side first.
        let torus = shape("(x^2 + y^2 + z^2 + 0.75)^2 - 4 (x^2 + z^2)", 2.0);
        assert!(torus.intersect(&Ray::new(Vec3::new(0.0, 3.0, 0.0), -Vec3::Y)).is_none());
        let t = torus.intersect(&Ray::new(Vec3::new(-3.0, 0.0, 0.0), Vec3::X)).unwrap();
        assert!((t - 1.5).abs() < 1e-5, "{t}");
        // A double root: the plane y = 0 touched by y² = 0.
        let touch = shape("y^2", 1.0);
        let t = touch.intersect(&Ray::new(Vec3::new(0.0, 0.5, 0.0), -Vec3::Y)).unwrap();
        assert!((t - 0.5).abs() < 1e-4, "{t}");
        // √ of negatives is no surface: f is undefined there, not zero.
        let half = shape("sqrt(-x) - 0.5", 1.0);
        assert!(half.intersect(&Ray::new(Vec3::new(0.8, 0.0, 3.0), -Vec3::Z)).is_none());
        let t = half.intersect(&Ray::new(Vec3::new(-3.0, 0.0, 0.0), Vec3::X)).unwrap();
        assert!((t - 2.75).abs() < 1e-4, "{t}");
    }

    #[test]
    fn a_starved_search_is_counted() {
        let s = ImplicitSurface::new(
            eq("sin(40 x) sin(40 y) sin(40 z) - 0.1"),
            Aabb::new(Vec3::splat(-1.0), Vec3::ONE),
            16,
        )
        .unwrap();
        let _ = s.intersect(&Ray::new(Vec3::new(0.01, 0.02, 3.0), -Vec3::Z));
        assert_eq!(s.give_ups(), 1);
        let inverted = Aabb {
            min: Vec3::ONE,
            max: Vec3::ZERO,
        };
        assert!(ImplicitSurface::new(eq("x"), inverted, 100).is_err());
    }
}
