//! Compiling a hot function twice: for the baseline CPU and for AVX-512, chosen at run time.
//!
//! The functions this wraps do element-wise IEEE arithmetic only (Rust never reassociates or
//! fuses multiply-adds on its own), so both versions compute the same bits; the AVX-512 one just
//! does it eight lanes at a time.

/// Defines `fn $name(args) { body }` compiled twice, for the baseline target and with AVX-512
/// enabled, and calls the AVX-512 one when the CPU has it. Use it for loops that should
/// vectorise, including bodies called from other threads (a closure handed to rayon does not
/// inherit its caller's target features).
macro_rules! multiversion {
    ($(#[$attr:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$attr])*
        #[allow(clippy::too_many_arguments)]
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            #[allow(clippy::too_many_arguments)]
            fn body($($arg: $ty),*) $(-> $ret)? $body

            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2")]
            #[allow(clippy::too_many_arguments)]
            unsafe fn avx512($($arg: $ty),*) $(-> $ret)? {
                body($($arg),*)
            }

            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU supports the features `avx512` is compiled for.
                return unsafe { avx512($($arg),*) };
            }
            body($($arg),*)
        }
    };
}

pub(crate) use multiversion;
