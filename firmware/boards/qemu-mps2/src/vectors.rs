//! The interrupt part of the vector table (cortex-m-rt's `device` feature
//! expects the device to supply it): the AN386 image has 32 external
//! interrupts (QEMU's `num-irq`). The image polls and enables none, so all
//! point at cortex-m-rt's `DefaultHandler`.

/// External interrupts of the MPS2 AN385/AN386 images.
const IRQ_COUNT: usize = 32;

extern "C" {
    /// cortex-m-rt's default handler (a user `#[exception] fn DefaultHandler` overrides it).
    fn DefaultHandler();
}

/// Placed by `link.x` right after the 16 system exception vectors.
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
static __INTERRUPTS: [unsafe extern "C" fn(); IRQ_COUNT] = [DefaultHandler; IRQ_COUNT];
